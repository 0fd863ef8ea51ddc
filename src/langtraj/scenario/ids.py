"""Window ids, and the map group a window is held out with (docs/data.md, 'Splits').

Windows of one synthesized SUMO run share a road network and its traffic, and windows cut from one real scene
share that scene: a split that put such windows on both sides would test on maps the model has seen. So
splits are decided per *map group*: the SUMO run for synthesized windows, the scene for real ones.
"""

from __future__ import annotations

import re

SYNTH_ID = re.compile(r"^(?P<run>[A-Za-z0-9_]+-\d{10})-(?P<centre>\d+)-(?P<start>\d{5})$")
"""A synthesized window's id: `{kind}-{seed:010d}-{centre}-{start:05d}`; `{kind}-{seed}` names its SUMO run."""


def synth_window_id(kind: str, seed: int, centre: int, start: int) -> str:
    """The id of a synthesized window: run (`kind`, shard `seed`), junction `centre`, first step `start`."""
    return f"{kind}-{seed:010d}-{centre}-{start:05d}"


def cut_window_id(scene_id: str, start: int) -> str:
    """The id of the window starting at step `start` of a longer scene (`scenario.windowing.cut_window`)."""
    return f"{scene_id}_w{start}"


def parent_scene_id(scenario_id: str, window_start: int) -> str:
    """The scene a window was cut from: the id without the `_w{start}` suffix `cut_window_id` adds."""
    suffix = f"_w{window_start}"
    return scenario_id[: -len(suffix)] if scenario_id.endswith(suffix) else scenario_id


def map_group(scenario_id: str, window_start: int = 0) -> str:
    """The group a window is split with: `{kind}-{seed}` (its SUMO run) for synthesized windows, the id of the
    scene it was cut from for every other (so real scenes split as they did before runs were grouped)."""
    scene = parent_scene_id(scenario_id, window_start)
    match = SYNTH_ID.match(scene)
    return match["run"] if match else scene
