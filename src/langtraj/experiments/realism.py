"""The closed-loop realism table of docs/experiments.md ('Closed-loop realism'): each method drives
every sim agent of each window, without text, and is scored with the WOSAC 2025 metrics, the share of
(rollout, vehicle) pairs that leave the road at some step, and the share of (rollout, sim agent) pairs
that collide. It holds the paper's closed-loop ablation (open-loop K = 100, K = 5, closed-loop training
with and without teacher forcing) beside the baselines, and the selection and guidance variants.

    langtraj experiment realism --method NAME=SPEC ... --data NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]] ... \\
        [--windows N] [--rollouts R] [--candidates M] [--seed S] [--json OUT]
    langtraj experiment realism --config configs/experiments/realism-heldout-maps.yaml   # the same as YAML

SPEC is `constant_velocity`, `stationary`, `log_replay` (a labelled baseline that reads the future), or
a checkpoint (`shipped`: the one inside the package), optionally followed by `|selector=NAME`,
`|guidance=COST:WEIGHT[+COST:WEIGHT]`, `|guided_steps=N` (the defaults' guidance at the last N denoising steps
only), `|warm_steps=N` (replans warm-started from the executed plan, `sim.policies.LangTrajPolicy`),
`|temperature=T` (the sampler's noise scaled by T), `|refresh_map` (each replan's map around the agents then),
`|hold_parked` (agents parked in the log stand still unless prompted), `|rolling` (one rolling plan per agent,
denoised once per replan: a rolling checkpoint, `model.rolling`), `|project=N` (hard constraints at the
last N denoising steps: on the road and apart, `guidance.projection`; 0: off), `|project_choice=0` (the plan
assembled agent by agent by `per_agent` selection is not projected again, `HardConstraints.on_choice`),
`|polish=N` (N descent steps polishing projected plans onto the road, `HardConstraints.polish`; 0: none),
`|polish_steps=N` (the polish judges the plans' first N steps, `HardConstraints.polish_steps`; 0: all of them),
`|defaults` and `|dense`.
A checkpoint row runs as the paper's (`min_collision`, no guidance) unless its spec says otherwise;
`|defaults` adds `langtraj simulate`'s default guidance and selection (on-road guidance, no-collision
guidance per agent pair, `per_agent` selection; `sim.policies`). Every model row attends locally in
scenes larger than its training scenes (docs/model.md, 'Local attention') unless `|dense` asks for dense
attention.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.experiments.base import EXPERIMENTS, Experiment
from langtraj.experiments.common import (
    DatasetSpec,
    SimulationSettings,
    cell,
    held_out_windows,
    markdown_table,
    nanmean,
    parse_named,
    require_items,
    window_kind,
    wosac_figures,
)
from langtraj.guidance.projection import HardConstraints
from langtraj.metrics.features import SceneMap
from langtraj.metrics.flow import FLOW_KEYS, traffic_flow
from langtraj.model.checkpoint import load_model
from langtraj.rollouts.baselines import generate_baseline
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.model import Scenario
from langtraj.sim.checkpoints import checkpoint_path
from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import simulate
from langtraj.sim.failures import BREAKDOWN_KEYS, OFFROAD_CAUSES, FailureScene, classify_failures
from langtraj.sim.policies import DEFAULT_HARD_CONSTRAINTS, POLICIES, LangTrajPolicy, LoadedModel
from langtraj.sim.terms import scene_wide_terms

COLUMNS = ("meta", "kinematic", "interactive", "map", "offroad", "collision")
PAPER: dict[str, Any] = {
    "selector": "min_collision",
    "on_road": 0.0,
    "no_collision": 0.0,
    "hard_constraints": 0,
    "hold_parked": False,
}
"""A checkpoint row's settings unless `|defaults` asks for `langtraj simulate`'s: the paper's (no realism
guidance, no hard constraints, `min_collision` selection)."""
BASELINE_POLICIES = ("constant_velocity", "log_replay")
ROLLOUT_BASELINES = ("stationary",)


@dataclass(frozen=True)
class Method:
    """One row: a baseline, or a checkpoint with its selector and scene-wide guidance (`COST=WEIGHT`). From YAML
    a mapping of these fields, or the `NAME=SPEC` shorthand (see the module docstring)."""

    name: str
    baseline: str | None = None
    checkpoint: Path | None = None
    selector: str | None = None
    guidance: tuple[str, ...] = ()
    defaults: bool = False  # `langtraj simulate`'s default guidance and selection besides the spec's
    dense: bool = False  # dense attention in scenes larger than the training scenes (default: local)
    guided_steps: int | None = None  # the last N denoising steps get the defaults' guidance (None: the default)
    warm_steps: int | None = None  # replans start from the executed plan noised to the last N steps (None: fresh)
    temperature: float = 1.0  # the sampler's noise scaled by this
    refresh_map: bool = False  # each replan's map around the agents' positions then (else the start's)
    hold_parked: bool = False  # agents parked in the log stand still unless prompted (else the row's setting)
    rolling: bool = False  # one rolling plan per agent, one network call per replan (a rolling checkpoint)
    project: int | None = None  # hard constraints at the last N denoising steps (0: off); None: the row's setting
    project_choice: bool = True  # with hard constraints, the executed plan assembled per agent is projected again
    polish: int | None = None  # with hard constraints, descent steps polishing plans onto the road (None: the default)
    polish_steps: int | None = None  # the plan's first steps the polish judges (None: the default; 0: all of them)

    def __post_init__(self) -> None:
        if (self.baseline is None) == (self.checkpoint is None):
            raise InputError(f"{self.name}: give a baseline or a checkpoint, not both or neither", where="--method")
        if self.baseline is not None:
            if self.baseline not in BASELINE_POLICIES + ROLLOUT_BASELINES:
                known = ", ".join(BASELINE_POLICIES + ROLLOUT_BASELINES)
                raise InputError(f"unknown baseline {self.baseline!r}; known: {known}", where="--method")
            options = (self.selector, self.guidance, self.defaults, self.dense, self.guided_steps, self.warm_steps,
                       self.refresh_map, self.project, self.hold_parked, self.rolling, self.polish,
                       self.polish_steps)  # fmt: skip
            if any(o not in (None, (), False) for o in options) or self.temperature != 1.0 or not self.project_choice:
                raise InputError(f"baseline {self.baseline} takes no options", where="--method")
        scene_wide_terms(self.guidance)  # checked now, before anything runs

    @classmethod
    def parse(cls, item: str) -> Method:
        """`NAME=SPEC` (see the module docstring), or a one-line InputError."""
        name, spec = parse_named(item, "--method", "NAME=SPEC")
        head, *options = spec.split("|")
        if head in BASELINE_POLICIES + ROLLOUT_BASELINES:
            if options:
                raise InputError(f"baseline {head} takes no options, got {options}", where="--method")
            return cls(name, baseline=head)
        settings: dict[str, str] = {}
        flags = {"defaults", "dense", "refresh_map", "hold_parked", "rolling"}
        for option in (o for o in options if o not in flags):
            key, eq, value = option.partition("=")
            known = ("selector", "guidance", "guided_steps", "warm_steps", "temperature", "project", "project_choice",
                     "polish", "polish_steps")  # fmt: skip
            if not eq or key not in known:
                raise InputError(
                    "expected selector=NAME, guidance=COST:WEIGHT, guided_steps=N, warm_steps=N, temperature=T, "
                    "project=N, project_choice=0|1, polish=N, polish_steps=N, defaults, dense, refresh_map, "
                    "hold_parked or rolling, "
                    f"got {option!r}",
                    where="--method",
                )
            settings[key] = value
        return cls(
            name,
            checkpoint=Path(head),
            selector=settings.get("selector"),
            guidance=tuple(g.replace(":", "=") for g in settings.get("guidance", "").split("+") if g),
            defaults="defaults" in options,
            dense="dense" in options,
            refresh_map="refresh_map" in options,
            hold_parked="hold_parked" in options,
            rolling="rolling" in options,
            guided_steps=_int_option(settings, "guided_steps"),
            warm_steps=_int_option(settings, "warm_steps"),
            temperature=_float_option(settings, "temperature", 1.0),
            project=_int_option(settings, "project"),
            project_choice=_int_option(settings, "project_choice") != 0,
            polish=_int_option(settings, "polish"),
            polish_steps=_int_option(settings, "polish_steps"),
        )

    def load(self) -> LoadedModel | None:
        """The method's model (None for a baseline), loaded once for every window."""
        return None if self.checkpoint is None else load_model(checkpoint_path(self.checkpoint))

    def rollouts(
        self, scenario: Scenario, config: SimConfig, candidates: int, steps: int, loaded: LoadedModel | None
    ) -> Rollouts:
        """R rollouts of every sim agent of `scenario` (`loaded`: this method's `load()`)."""
        if self.baseline in ROLLOUT_BASELINES:
            return generate_baseline(self.baseline, scenario, config.rollouts)
        if self.baseline is not None:
            policy = POLICIES.get(self.baseline)()
        else:
            assert loaded is not None
            model, data = loaded
            options: dict[str, Any] = {} if self.defaults else dict(PAPER)
            if self.selector:
                options["selector"] = self.selector
            if self.guided_steps is not None:
                options["guided_steps"] = self.guided_steps
            if self.warm_steps is not None:
                options["warm_steps"] = self.warm_steps
            if self.temperature != 1.0:
                options["temperature"] = self.temperature
            if self.refresh_map:
                options["refresh_map"] = True
            if self.hold_parked:
                options["hold_parked"] = True
            if self.rolling:
                options["rolling"] = True
            if self.project is not None:
                options["hard_constraints"] = self.project
            request = SimRequest(
                guidance=self.guidance,
                candidates=candidates,
                steps=min(steps, model.schedule.num_steps),
                dense_attention=self.dense,
                **options,
            )
            policy = LangTrajPolicy(model, data, request, constraints=self.constraints(request.hard_constraints))
        return simulate(scenario, policy, config).rollouts

    def constraints(self, project: int | None) -> HardConstraints | None:
        """The hard constraints of a row that asks for them at the last `project` denoising steps (None: the
        default's), with its `polish` and `project_choice`; None when `project` is 0 (off)."""
        if project == 0:
            return None
        constraints = DEFAULT_HARD_CONSTRAINTS if project is None else HardConstraints(steps=project)
        if constraints is None:
            return None
        polish = constraints.polish if self.polish is None else self.polish
        judged = constraints.polish_steps if self.polish_steps is None else (self.polish_steps or None)
        return replace(
            constraints, on_choice=self.project_choice and constraints.on_choice, polish=polish, polish_steps=judged
        )


def _int_option(settings: dict[str, str], key: str) -> int | None:
    """`settings[key]` as an integer (None when absent), or a one-line InputError."""
    return _number_option(settings, key, int, "an integer")


def _float_option(settings: dict[str, str], key: str, default: float) -> float:
    """`settings[key]` as a number (`default` when absent), or a one-line InputError."""
    value = _number_option(settings, key, float, "a number")
    return default if value is None else value


def _number_option(settings: dict[str, str], key: str, kind: type, what: str):
    if key not in settings:
        return None
    try:
        return kind(settings[key])
    except ValueError:
        raise InputError(f"{key} must be {what}, got {settings[key]!r}", where="--method") from None


def dataset_windows(spec: DatasetSpec, settings: SimulationSettings) -> tuple[list[Scenario], SimConfig]:
    """The windows a closed-loop table simulates for dataset `spec` (`windows_of`; none is an error naming the
    labels) and their simulation config, announced on stdout."""
    scenes = windows_of(spec, settings.windows)
    if not scenes:
        raise InputError("no window logs 8 s after its current step", path=spec.labels)
    rollouts = spec.rollouts or settings.rollouts
    print(f"\n{spec.name}: {len(scenes)} windows, {rollouts} rollouts, {settings.candidates} candidates per replan, "
          f"K = {settings.steps}")  # fmt: skip
    return scenes, SimConfig(rollouts=rollouts, seed=settings.seed)


def windows_of(spec: DatasetSpec, limit: int | None) -> list[Scenario]:
    """Windows of a dataset split that log the 8 s the metrics score (at most `limit`, in dataset order)."""
    found = []
    for _, scenario in held_out_windows(spec):
        if limit is not None and len(found) >= limit:
            break
        if scenario.logs_future():
            found.append(scenario)
    return found


def realism_table(
    methods: Sequence[Method],
    scenes: Sequence[Scenario],
    config: SimConfig,
    candidates: int,
    steps: int,
    loaded: Mapping[str, LoadedModel | None],
    progress: Callable[[str], None] | None = None,
) -> dict:
    """Mean figures per method over `scenes`, the per-window figures (WOSAC, collision and offroad, and their shares
    per cause, `sim.failures.BREAKDOWN_KEYS`), and seconds per simulation (`loaded`: each method's model by name, as
    `Method.load` gives it)."""
    maps = [SceneMap.from_scenario(scenario) for scenario in scenes]  # once for every method
    causes = [FailureScene.build(scenario, scene_map) for scenario, scene_map in zip(scenes, maps, strict=True)]
    table, per_window = {}, {}
    for method in methods:
        rows, seconds = [], []
        for scenario, scene_map, scene in zip(scenes, maps, causes, strict=True):
            begin = time.perf_counter()
            rollouts = method.rollouts(scenario, config, candidates, steps, loaded[method.name])
            seconds.append(time.perf_counter() - begin)
            # The cause analysis finds the same off-road and collision events as the rates count: computed once.
            report = classify_failures(scenario, rollouts, scene=scene)
            figures = wosac_figures(scenario, rollouts, scene_map) | report.shares()
            figures |= {"offroad": report.offroad_rate, "collision": report.collision_rate}
            figures |= traffic_flow(scenario, rollouts).as_dict()
            rows.append(figures | {"scenario_id": scenario.scenario_id})
        per_window[method.name] = rows
        table[method.name] = {c: nanmean([r[c] for r in rows]) for c in (*COLUMNS, *BREAKDOWN_KEYS, *FLOW_KEYS)} | {
            "min_meta": min(r["meta"] for r in rows),
            "windows": len(rows),
            "seconds_per_simulation": float(np.median(seconds)),
        }
        if progress:
            progress(f"  {method.name}: meta {table[method.name]['meta']:.3f} ({len(rows)} windows)")
    return {"table": table, "per_window": per_window}


FLOW_COLUMNS = ("speed_ratio", "stopped", "stopped_log")
"""The flow figures a realism table shows (`metrics.flow`): speed against the log, ending stopped, and the log's."""
FLOW_HEADER = ("speed / log", "end stopped", "log end stopped")


def markdown(table: dict[str, dict[str, float]]) -> str:
    """The table as Markdown (NaN as a dash)."""
    header = ("method", "meta", "kinematic", "interactive", "map", "offroad", "collision", "lowest meta")
    rows = [
        (name, *(cell(r[c]) for c in COLUMNS), cell(r["min_meta"]), *(cell(r[c]) for c in FLOW_COLUMNS),
         _seconds(r["seconds_per_simulation"]))
        for name, r in table.items()
    ]  # fmt: skip
    return markdown_table((*header, *FLOW_HEADER, "s per simulation"), rows)


def _seconds(value: float) -> str:
    return "–" if math.isnan(value) else f"{value:.1f}"


OWN_ROWS = ("onramp", "roundabout")
"""Network kinds every realism table also reports on their own (merges and roundabouts: where the model's agents
left the road and collided most, docs/experiments.md 'Traffic that stays on the road')."""


def by_kind(per_window: Mapping[str, list[dict]], kinds: Sequence[str], chosen: Sequence[str]) -> dict[str, dict]:
    """Each `chosen` kind that has windows (`kinds[i]`: window i's): its methods' mean figures over those windows,
    as `realism_table`'s table."""
    out = {}
    for kind in (k for k in chosen if k in kinds):
        rows = {name: [r for r, k in zip(per, kinds, strict=True) if k == kind] for name, per in per_window.items()}
        out[kind] = {
            name: {c: nanmean([r[c] for r in of_kind]) for c in (*COLUMNS, *FLOW_COLUMNS)}
            | {"min_meta": min(r["meta"] for r in of_kind), "windows": len(of_kind), "seconds_per_simulation": math.nan}
            for name, of_kind in rows.items()
        }
    return out


def breakdown_markdown(table: dict[str, dict[str, float]]) -> str:
    """Each row's offroad and collision shares and their parts per cause (`sim.failures`; keys `offroad`,
    `collision` and `BREAKDOWN_KEYS`) as Markdown, NaN as a dash: the causes of a kind sum to its share, except
    `offroad:no_road_edges`, the share of vehicle pairs offroad could not be measured on."""
    columns = ("offroad", *(f"offroad:{c}" for c in OFFROAD_CAUSES[1:]), "offroad:no_road_edges", "collision",
               *(k for k in BREAKDOWN_KEYS if k.startswith("collision:")))  # fmt: skip
    header = [c.replace("_", " ") for c in columns]
    header[columns.index("offroad:no_road_edges")] = "offroad not measured"
    rows = [(name, *(cell(r.get(c)) for c in columns)) for name, r in table.items()]
    return markdown_table(("method", *header), rows)


SCENE_COLUMNS = ("meta", "collision", "offroad", *FLOW_COLUMNS)
"""A per-scene row (`per_scene_markdown`): realism, the rates against the stationary floor, and the flow against the
log (`metrics.flow`)."""


def per_scene(per_window: Mapping[str, list[dict]]) -> dict[str, dict[str, dict[str, float]]]:
    """Each scene's figures per method, the means over its windows (a scene's windows share its scenario id)."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for name, rows in per_window.items():
        scenes = sorted({r["scenario_id"] for r in rows})
        for scene in scenes:
            of_scene = [r for r in rows if r["scenario_id"] == scene]
            figures = {c: nanmean([r[c] for r in of_scene]) for c in SCENE_COLUMNS}
            out.setdefault(scene, {})[name] = figures
    return out


def per_scene_markdown(scenes: Mapping[str, Mapping[str, Mapping[str, float]]]) -> str:
    """`per_scene` as Markdown, a row per (scene, method): NaN as a dash."""
    header = ("scene", "method", "meta", "collision", "offroad", *FLOW_HEADER)
    rows = [(scene, name, *(cell(r[c]) for c in SCENE_COLUMNS)) for scene, methods in scenes.items()
            for name, r in methods.items()]  # fmt: skip
    return markdown_table(header, rows)


@dataclass(frozen=True, kw_only=True)
class RealismSettings(SimulationSettings):
    """The realism table's settings: its rows (`methods`), and the simulation settings every closed-loop table has."""

    methods: tuple[Method, ...]

    def __post_init__(self) -> None:
        require_items(self.methods, "--method")
        super().__post_init__()


@EXPERIMENTS.register
class RealismExperiment(Experiment):
    """`langtraj experiment realism`: closed-loop realism per method, every agent driven, one table per dataset."""

    name = "realism"
    settings = RealismSettings

    def tables(self, settings: RealismSettings) -> dict[str, dict]:
        loaded = {m.name: m.load() for m in settings.methods}  # once for every dataset
        results = {}
        for spec in settings.datasets:
            scenes, config = dataset_windows(spec, settings)
            candidates, steps, rollouts = settings.candidates, settings.steps, config.rollouts
            result = realism_table(settings.methods, scenes, config, candidates, steps, loaded, print)
            results[spec.name] = result  # the per-scene and per-kind tables below are added to it
            result["rollouts"] = rollouts
            print(markdown(result["table"]))
            print(f"\n{spec.name}, offroad and collisions by cause (sim.failures):")
            print(breakdown_markdown(result["table"]))
            result["per_scene"] = per_scene(result["per_window"])
            print(f"\n{spec.name}, per scene: the vehicles moving at the start against their log (metrics.flow):")
            print(per_scene_markdown(result["per_scene"]))
            kinds = [window_kind(scenario, spec.name) for scenario in scenes]
            result["by_kind"] = by_kind(result["per_window"], kinds, OWN_ROWS)
            for kind, table in result["by_kind"].items():
                print(f"\n{spec.name}, {kind} windows only:")
                print(markdown(table))
        return results
