"""The one-command demo: one scene simulated three ways (unconditioned, with a prompt, and safety-critical
with collision guidance plus the prompt), rendered side by side, as in the paper's teaser figure.

Without a scene file the demo synthesizes a signalized intersection with SUMO and labels it with
InterDrive; the scene is a window with an interaction prompt between two vehicles the model drives, whose
other agent becomes the adversary and its target agent the target. The prompt is counterfactual: a
feasible behaviour of the target agent that the log does not show and the unconditioned run does not do
(going first instead of yielding to the adversary, or the other way round, before a turn the lane
allows, a lane change, stopping, ...; `interdrive.counterfactual`), preferring behaviours for which the map
gives a target to steer toward (`interdrive.targets`), else the logged interaction prompt.
The summary says, per panel, the share of rollouts in which the labelers find the prompt followed; the video
marks the prompted agent's target (`viz.marks`).

It lives among the experiments because, like them, it composes the packages below: synthesis, labels,
simulation and rendering (`sim` itself reads neither `synth` nor `viz`). See docs/simulation.md.
"""

from __future__ import annotations

import contextlib
import json
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.interdrive.adherence import AdherenceChecker, prompt_facts
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.counterfactual import Alternative, feasible_alternatives
from langtraj.interdrive.dataset import BuildConfig, PromptEntry, label_file, load_window
from langtraj.interdrive.targets import TargetUnavailable, derive_target
from langtraj.metrics.instruction_following import rollout_scenario
from langtraj.roads import MapIndex
from langtraj.rollouts import Rollouts
from langtraj.scenario.io import expand_scenario_paths
from langtraj.scenario.model import HISTORY_STEPS, WINDOW_STEPS, Scenario
from langtraj.scenario.types import AgentType
from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import SimResult, simulate
from langtraj.sim.setup import build_policy
from langtraj.sim.summary import simulation_summary

if TYPE_CHECKING:
    from langtraj.viz.marks import TargetMark

PANEL_PX = 480
PREFERRED_TYPES = ("yielding", "following", "merging", "passing", "overtaking", "lane_change")
"""Interaction types the demo prefers for its scene's prompt, first to last."""

COUNTERFACTUAL_ORDER = (
    Behaviour.GO_FIRST,
    Behaviour.YIELD,
    Behaviour.TURN_LEFT,
    Behaviour.TURN_RIGHT,
    Behaviour.GO_STRAIGHT,
    Behaviour.LANE_CHANGE_LEFT,
    Behaviour.LANE_CHANGE_RIGHT,
    Behaviour.STOP,
    Behaviour.SLOW_DOWN,
    Behaviour.SPEED_UP,
)
"""Counterfactual behaviours the demo prefers, first to last (pair behaviours toward the adversary first); those
for which the map gives no target come after every one for which it does, and behaviours not listed last."""


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
            if not scenario.logs_future():
                continue
            ids = {int(i) for i in scenario.agents.ids[prioritized_agents(scenario, driven)]}
            prompt = _pick_prompt(scenario, record.prompts, ids)
            if prompt is not None:
                return DemoScene(scenario, path, record.record, prompt)
    raise InputError("no window with an interaction prompt between two vehicles the model drives", path=files[0])


def choose_counterfactual(
    scenario: Scenario, target: int, other: int, unconditioned: Rollouts
) -> tuple[Alternative | None, AdherenceChecker]:
    """The first feasible behaviour of `target` (`COUNTERFACTUAL_ORDER`; pair behaviours only toward `other`)
    that the log does not show and no unconditioned rollout does, judged by the labelers; None when none.

    Behaviours for which the map gives a target (`has_target`) come first: a prompt steers by its text, by
    guidance toward that target and by adherence-first selection, and without a target it loses the guidance.
    A feasible single-agent behaviour always has one (`interdrive.targets`); going first where the map shows no
    crossing is offered as undecided, without one."""
    index = MapIndex.build(scenario.road_map)
    checker = AdherenceChecker.build(scenario, map_index=index)
    options = [
        a
        for a in feasible_alternatives(scenario, target, index, logged=checker.logged)
        if not a.logged and a.other_id in (None, other)
    ]
    rank = {b: i for i, b in enumerate(COUNTERFACTUAL_ORDER)}
    options.sort(key=lambda a: (not has_target(scenario, a, index), rank.get(a.behaviour, len(rank))))
    found = rollout_facts(scenario, unconditioned, checker)  # one labelling per rollout for every option
    return next((o for o in options if not any(o.facts <= f for f in found)), None), checker


def has_target(scenario: Scenario, alternative: Alternative, index: MapIndex) -> bool:
    """Whether the map gives `alternative`'s behaviour a target at the current step (`derive_target`)."""
    try:
        derive_target(scenario, alternative.track_id, alternative.behaviour, index, other_id=alternative.other_id)
    except TargetUnavailable:
        return False
    return True


def rollout_facts(scenario: Scenario, rollouts: Rollouts, checker: AdherenceChecker) -> list[frozenset]:
    """The facts the labelers find in each rollout."""
    return [checker.facts(rollout_scenario(scenario, rollouts, r)) for r in range(rollouts.num_rollouts)]


def followed_share(scenario: Scenario, rollouts: Rollouts, facts: frozenset, checker: AdherenceChecker) -> float:
    """The share of rollouts in which the labelers find every one of a prompt's `facts`."""
    return float(np.mean([facts <= found for found in rollout_facts(scenario, rollouts, checker)]))


def synthesize_scene(folder: Path, seed: int, driven: int | None = None) -> DemoScene:
    """Synthesize a few signalized-intersection windows with SUMO into `folder` and pick one."""
    from langtraj.synth.factory import FactoryConfig, run_factory
    from langtraj.synth.network import parse_kinds

    run_factory(FactoryConfig(kinds=parse_kinds("signalized"), windows=4, seed=seed, out=folder), progress=False)
    return find_scene(expand_scenario_paths([folder / "shards"]), driven)


@dataclass(frozen=True)
class Panel:
    """One panel of the demo video: rollout 0 of `result`, its caption, the agents outlined and the targets
    marked on the map."""

    result: SimResult
    caption: str
    highlight: tuple[int, ...] = ()
    marks: tuple[TargetMark, ...] = ()


def _panel(panel: Panel, follow: int):
    from langtraj.viz import RenderConfig, TopDownRenderer

    config = RenderConfig(
        size_px=PANEL_PX, follow_track_id=follow, view_extent_m=90.0, highlight_ids=panel.highlight,
        caption=panel.caption, marks=panel.marks,
    )  # fmt: skip
    scene = panel.result.scenario(0)
    start = max(scene.current_index - (HISTORY_STEPS - 1), 0)  # the window the simulation ran
    steps = range(start, start + WINDOW_STEPS)
    return TopDownRenderer(scene, config, steps=steps), steps


def write_side_by_side(path: Path, panels: list[Panel], follow: int) -> int:
    """One video of the panels next to each other; returns the number of frames."""
    from langtraj.viz.video import write_mp4

    opened = [_panel(panel, follow) for panel in panels]
    with contextlib.ExitStack() as stack:
        renderers = [stack.enter_context(renderer) for renderer, _ in opened]
        frames = (np.concatenate([r.frame(t) for r in renderers], axis=1) for t in opened[0][1])
        with atomic_path(path) as tmp:
            return write_mp4(tmp, frames, 10.0)


def demo_panels(results: dict[str, SimResult], text: str, adversary: int, target: int, prompted: tuple[int, ...]):
    """The three panels, each marking the targets its own run steered toward (`report["prompt"]`).

    The unconditioned panel marks the prompt panel's targets too, captioned so: a target is derived from the
    scene at the current step, which the three runs share, so these are exactly where the prompt would take the
    agent; drawn beside the run that was not asked, they show what it does instead (and what `followed` judges
    its 0 against)."""
    from langtraj.viz.marks import marks_from_prompt

    marks = {name: marks_from_prompt(r.report.get("prompt")) for name, r in results.items()}
    unconditioned = "unconditioned" + (f"; marked: where the prompt takes @{target}" if marks["prompt"] else "")
    return [
        Panel(results["unconditioned"], unconditioned, (), marks["prompt"]),
        Panel(results["prompt"], text, prompted, marks["prompt"]),
        Panel(
            results["safety-critical"],
            f"{text} + @{adversary} collides with @{target}",
            prompted,
            marks["safety-critical"],
        ),
    ]


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
        config = SimConfig(rollouts=rollouts, seed=seed)
        results, summaries = {}, {}

        def run(name: str, request: SimRequest) -> None:
            policy, described = build_policy(scene.scenario, request, loaded)
            results[name] = simulate(scene.scenario, policy, config)
            summaries[name] = simulation_summary(results[name], policy=request.policy, **described)

        run("unconditioned", SimRequest(**base))
        alternative, checker = choose_counterfactual(
            scene.scenario, target, adversary, results["unconditioned"].rollouts
        )
        text = scene.prompt.text if alternative is None else alternative.prompt.text
        facts = prompt_facts(scene.prompt) if alternative is None else alternative.facts
        run("prompt", SimRequest(**base, prompts=(text,)))
        run("safety-critical", SimRequest(**base, prompts=(text,), adversary=adversary, target=target))
        followed = {name: followed_share(scene.scenario, r.rollouts, facts, checker) for name, r in results.items()}
        out.mkdir(parents=True, exist_ok=True)
        kept = out / "scene.tfrecord"
        if scene_file is None:
            from langtraj.scenario.io import write_scenarios

            write_scenarios(kept, [scene.scenario])
        if video:
            panels = demo_panels(results, text, adversary, target, tuple(scene.prompt.mentions))
            write_side_by_side(out / "demo.mp4", panels, follow=target)
    summary = {
        "scene": str(kept if scene_file is None else scene.source),
        "record": 0 if scene_file is None else scene.index,
        "prompt": text,
        "prompt_kind": "logged" if alternative is None else "counterfactual",
        "behaviour": None if alternative is None else alternative.behaviour.value,
        "logged_prompt": scene.prompt.text,
        "followed": followed,
        "adversary": adversary,
        "target": target,
        "seconds": time.perf_counter() - begin,
        "runs": summaries,
    }
    with atomic_path(out / "summary.json") as tmp_path:
        tmp_path.write_text(json.dumps(summary, indent=2))
    return summary
