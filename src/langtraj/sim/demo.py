"""The one-command demo: one scene simulated three ways (unconditioned, with a prompt, and safety-critical
with collision guidance plus the prompt), rendered side by side, as in the paper's teaser figure.

Without a scene file the demo synthesizes a signalized intersection with SUMO and labels it with
InterDrive; the prompt is one of its interaction prompts between two vehicles the model drives, the
prompt's other agent becomes the adversary and its target agent the target.

See docs/simulation.md.
"""

from __future__ import annotations

import contextlib
import json
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.interdrive.dataset import BuildConfig, PromptEntry, label_file, load_window
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType
from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import SimResult, simulate
from langtraj.sim.setup import build_policy
from langtraj.sim.summary import simulation_summary

PANEL_PX = 480
PREFERRED_TYPES = ("yielding", "following", "merging", "passing", "overtaking", "lane_change")
"""Interaction types the demo prefers for its prompt, first to last."""


@dataclass(frozen=True)
class DemoScene:
    """The scene, where it came from (file and index) and the prompt the demo conditions on."""

    scenario: Scenario
    source: Path
    index: int
    prompt: PromptEntry


def _pick_prompt(scenario: Scenario, prompts, driven_ids: set[int]) -> PromptEntry | None:
    """An interaction prompt between two driven vehicles, preferring the `PREFERRED_TYPES` order."""
    agents = scenario.agents
    vehicles = {int(i) for i, t in zip(agents.ids, agents.types, strict=True) if t == AgentType.VEHICLE}
    usable = [
        p
        for p in prompts
        if p.subtype is not None and len(p.mentions) == 2 and set(p.mentions) <= driven_ids & vehicles
    ]
    rank = {kind: i for i, kind in enumerate(PREFERRED_TYPES)}
    usable.sort(key=lambda p: rank.get(p.subtype.split("/")[0], len(rank)))
    return usable[0] if usable else None


def find_scene(files: list[Path], driven: int | None = None) -> DemoScene:
    """The first window of `files` (InterDrive-labelled on the fly) with an interaction prompt between two
    vehicles the model drives (`driven`: its cap on the most important agents; None: every sim agent)."""
    from langtraj.scenario.selection import prioritized_agents

    for path in files:
        for record in label_file(path, BuildConfig()):
            scenario = load_window(record)
            if scenario.num_steps - scenario.current_index - 1 < 80:
                continue
            ids = {int(i) for i in scenario.agents.ids[prioritized_agents(scenario, driven)]}
            prompt = _pick_prompt(scenario, record.prompts, ids)
            if prompt is not None:
                return DemoScene(scenario, path, record.record, prompt)
    raise InputError("no window with an interaction prompt between two vehicles the model drives", path=files[0])


def synthesize_scene(folder: Path, seed: int, driven: int | None = None) -> DemoScene:
    """Synthesize a few signalized-intersection windows with SUMO into `folder` and pick one."""
    from langtraj.synth.factory import FactoryConfig, run_factory
    from langtraj.synth.network import parse_kinds

    run_factory(FactoryConfig(kinds=parse_kinds("signalized"), windows=4, seed=seed, out=folder), progress=False)
    return find_scene(sorted((folder / "shards").glob("*.tfrecord")), driven)


def _panel(result: SimResult, caption: str, highlight: tuple[int, ...], follow: int):
    from langtraj.viz import RenderConfig, TopDownRenderer

    config = RenderConfig(
        size_px=PANEL_PX, follow_track_id=follow, view_extent_m=90.0, highlight_ids=highlight, caption=caption
    )
    scene = result.scenario(0)
    start = max(scene.current_index - 10, 0)
    return TopDownRenderer(scene, config, steps=range(start, start + 91)), range(start, start + 91)


def write_side_by_side(path: Path, panels: list[tuple[SimResult, str, tuple[int, ...]]], follow: int) -> int:
    """One video of the panels next to each other; returns the number of frames."""
    from langtraj.viz.video import write_mp4

    opened = [_panel(result, caption, highlight, follow) for result, caption, highlight in panels]
    with contextlib.ExitStack() as stack:
        renderers = [stack.enter_context(renderer) for renderer, _ in opened]
        frames = (np.concatenate([r.frame(t) for r in renderers], axis=1) for t in opened[0][1])
        with atomic_path(path) as tmp:
            return write_mp4(tmp, frames, 10.0)


def run_demo(
    out: Path,
    *,
    checkpoint: Path | None = None,
    scene_file: Path | None = None,
    rollouts: int = 1,
    candidates: int = 4,
    seed: int = 0,
    video: bool = True,
) -> dict[str, Any]:
    """Simulate the demo scene unconditioned, with its prompt, and safety-critical; write demo.mp4 and
    summary.json into `out`. Returns the summary."""
    from langtraj.model.checkpoint import load_model
    from langtraj.sim.checkpoints import shipped_checkpoint

    begin = time.perf_counter()
    checkpoint = checkpoint or shipped_checkpoint()
    loaded = load_model(checkpoint)  # once for the three runs
    with tempfile.TemporaryDirectory(prefix="langtraj-demo-") as tmp:
        scene = synthesize_scene(Path(tmp), seed) if scene_file is None else find_scene([scene_file])
        target, adversary = scene.prompt.mentions
        base = {"checkpoint": checkpoint, "candidates": candidates}
        requests = {
            "unconditioned": SimRequest(**base),
            "prompt": SimRequest(**base, prompts=(scene.prompt.text,)),
            "safety-critical": SimRequest(**base, prompts=(scene.prompt.text,), adversary=adversary, target=target),
        }
        config = SimConfig(rollouts=rollouts, seed=seed)
        results, summaries = {}, {}
        for name, request in requests.items():
            policy, described = build_policy(scene.scenario, request, loaded)
            results[name] = simulate(scene.scenario, policy, config)
            summaries[name] = simulation_summary(results[name], policy=request.policy, **described)
        out.mkdir(parents=True, exist_ok=True)
        kept = out / "scene.tfrecord"
        if scene_file is None:
            from langtraj.scenario.io import write_scenarios

            write_scenarios(kept, [scene.scenario])
        prompted = tuple(scene.prompt.mentions)
        panels = [
            (results["unconditioned"], "unconditioned", ()),
            (results["prompt"], scene.prompt.text, prompted),
            (results["safety-critical"], f"{scene.prompt.text} + @{adversary} collides with @{target}", prompted),
        ]
        if video:
            write_side_by_side(out / "demo.mp4", panels, follow=target)
    summary = {
        "scene": str(kept if scene_file is None else scene.source),
        "record": 0 if scene_file is None else scene.index,
        "prompt": scene.prompt.text,
        "adversary": adversary,
        "target": target,
        "seconds": time.perf_counter() - begin,
        "runs": summaries,
    }
    with atomic_path(out / "summary.json") as tmp_path:
        tmp_path.write_text(json.dumps(summary, indent=2))
    return summary
