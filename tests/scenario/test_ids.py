"""Map groups: windows of one SUMO run, or of one real scene, are split together (docs/data.md, 'Map groups')."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from langtraj.interdrive.dataset import SPLITS, WindowLabels, WindowRecord, in_split, split_of
from langtraj.scenario.ids import SYNTH_ID, cut_window_id, map_group, parent_scene_id, synth_window_id


def test_a_synthesized_window_id_names_its_run():
    wid = synth_window_id("roundabout", 123456789, 3, 410)
    assert wid == "roundabout-0123456789-3-00410" and SYNTH_ID.match(wid)
    assert map_group(wid) == "roundabout-0123456789"
    assert map_group(synth_window_id("roundabout", 123456789, 0, 0)) == map_group(wid)
    assert map_group(synth_window_id("roundabout", 123456788, 3, 410)) != map_group(wid)
    assert map_group(synth_window_id("city", 123456789, 3, 410)) != map_group(wid)


def test_a_window_cut_from_a_real_scene_is_grouped_with_its_scene():
    assert parent_scene_id(cut_window_id("637f20ab", 91), 91) == "637f20ab"
    assert map_group(cut_window_id("637f20ab", 91), 91) == map_group("637f20ab") == "637f20ab"
    assert map_group("637f20ab_w91", 10) == "637f20ab_w91"  # only the window's own suffix is stripped
    assert map_group("not-a-synth-id-00001") == "not-a-synth-id-00001"


def _record(scenario_id: str, start: int = 0) -> WindowRecord:
    return WindowRecord(scenario_id, "shard", 0, start, 10, 91, (), WindowLabels(scenario_id, (), (), ()))


def test_no_sumo_run_falls_in_two_splits():
    rng = np.random.default_rng(0)
    records = [
        _record(synth_window_id(kind, int(seed), int(c), int(start)))
        for kind in ("city", "onramp", "zebra")
        for seed in rng.integers(0, 10**9, 40)
        for c, start in rng.integers(0, 900, (12, 2))
    ]
    for fraction in (0.05, 0.1, 0.3, 0.5):
        runs: dict[str, set[str]] = {}
        for record in records:
            runs.setdefault(map_group(record.scenario_id), set()).add(split_of(record, fraction))
        assert all(len(splits) == 1 for splits in runs.values())
        val = sum(splits == {"val"} for splits in runs.values())
        assert 0 < val < len(runs)  # both sides hold runs
        for record in records[:50]:
            assert in_split(record, "all") and in_split(record, "val", fraction) != in_split(record, "train", fraction)
    assert SPLITS == ("train", "val", "all")


def test_windows_of_one_real_scene_fall_in_one_split():
    window = _record(cut_window_id("long", 91), 91)
    other = replace(window, scenario_id=cut_window_id("long", 182), window_start=182)
    assert all(split_of(window, f) == split_of(other, f) for f in np.linspace(0.05, 0.95, 19))
