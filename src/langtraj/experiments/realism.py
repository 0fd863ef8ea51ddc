"""The closed-loop realism table of docs/experiments.md ('Closed-loop realism'): each method drives
every sim agent of each window, without text, and is scored with the WOSAC 2025 metrics, the share of
(rollout, vehicle) pairs that leave the road at some step, and the share of (rollout, sim agent) pairs
that collide. It holds the paper's closed-loop ablation (open-loop K = 100, K = 5, closed-loop training
with and without teacher forcing) beside the baselines, and the selection and guidance variants.

    langtraj experiment realism --method NAME=SPEC ... --data NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]] ... \\
        [--windows N] [--candidates M] [--seed S] [--json OUT]

SPEC is `constant_velocity`, `stationary`, `log_replay` (a labelled baseline that reads the future), or
a checkpoint, optionally followed by `|selector=NAME`, `|guidance=COST:WEIGHT[+COST:WEIGHT]`,
`|guided_steps=N` (the defaults' guidance at the last N denoising steps only), `|defaults` and `|dense`.
A checkpoint row runs as the paper's (`min_collision`, no guidance) unless its spec says otherwise;
`|defaults` adds `langtraj simulate`'s default guidance and selection (on-road guidance, no-collision
guidance per agent pair, `per_agent` selection; `sim.policies`). Every model row attends locally in
scenes larger than its training scenes (docs/model.md, 'Local attention') unless `|dense` asks for dense
attention.
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.interdrive.dataset import load_window
from langtraj.metrics.controllability import collision_rate, offroad_rate
from langtraj.metrics.features import SceneMap
from langtraj.metrics.wosac import evaluate_scenario
from langtraj.model.checkpoint import load_model
from langtraj.rollouts.baselines import generate_baseline
from langtraj.rollouts.container import FUTURE_STEPS, Rollouts
from langtraj.scenario.model import Scenario
from langtraj.sim.config import SimConfig
from langtraj.sim.engine import simulate
from langtraj.sim.experiments import DatasetSpec, held_out_records
from langtraj.sim.policies import POLICIES, LangTrajPolicy, LoadedModel
from langtraj.sim.terms import scene_wide_terms

COLUMNS = ("meta", "kinematic", "interactive", "map", "offroad", "collision")
BASELINE_POLICIES = ("constant_velocity", "log_replay")
ROLLOUT_BASELINES = ("stationary",)


@dataclass(frozen=True)
class Method:
    """One row: a baseline, or a checkpoint with its selector and scene-wide guidance (`NAME=WEIGHT`)."""

    name: str
    baseline: str | None = None
    checkpoint: Path | None = None
    selector: str | None = None
    guidance: tuple[str, ...] = ()
    defaults: bool = False  # `langtraj simulate`'s default guidance and selection besides the spec's
    dense: bool = False  # dense attention in scenes larger than the training scenes (default: local)
    guided_steps: int | None = None  # the last N denoising steps get the defaults' guidance (None: the default)
    loaded: LoadedModel | None = field(default=None, compare=False, repr=False)

    @classmethod
    def parse(cls, item: str) -> Method:
        """`NAME=SPEC` (see the module docstring), or a one-line InputError."""
        name, sep, spec = item.partition("=")
        if not sep or not name or not spec:
            raise InputError(f"expected NAME=SPEC, got {item!r}", where="--method")
        head, *options = spec.split("|")
        if head in BASELINE_POLICIES + ROLLOUT_BASELINES:
            if options:
                raise InputError(f"baseline {head} takes no options, got {options}", where="--method")
            return cls(name, baseline=head)
        settings: dict[str, str] = {}
        flags = {"defaults", "dense"}
        for option in (o for o in options if o not in flags):
            key, eq, value = option.partition("=")
            if not eq or key not in ("selector", "guidance", "guided_steps"):
                raise InputError(
                    f"expected selector=NAME, guidance=COST:WEIGHT, guided_steps=N, defaults or dense, got {option!r}",
                    where="--method",
                )
            settings[key] = value
        guidance = tuple(g.replace(":", "=") for g in settings.get("guidance", "").split("+") if g)
        scene_wide_terms(guidance)  # checked now, before anything runs
        return cls(
            name,
            checkpoint=Path(head),
            selector=settings.get("selector"),
            guidance=guidance,
            defaults="defaults" in options,
            dense="dense" in options,
            guided_steps=_int_option(settings, "guided_steps"),
        )

    def load(self) -> Method:
        """The method with its checkpoint loaded (once for every window)."""
        if self.checkpoint is None:
            return self
        return replace(self, loaded=load_model(self.checkpoint))

    def rollouts(self, scenario: Scenario, config: SimConfig, candidates: int, steps: int) -> Rollouts:
        """R rollouts of every sim agent of `scenario`."""
        if self.baseline in ROLLOUT_BASELINES:
            return generate_baseline(self.baseline, scenario, config.rollouts)
        if self.baseline is not None:
            policy = POLICIES.get(self.baseline)()
        else:
            assert self.loaded is not None
            model, data = self.loaded
            paper = {} if self.defaults else {"selector": "min_collision", "on_road": 0.0, "no_collision": 0.0}
            if self.selector:
                paper["selector"] = self.selector
            if self.guided_steps is not None:
                paper["guided_steps"] = self.guided_steps
            policy = LangTrajPolicy(
                model,
                data,
                terms=scene_wide_terms(self.guidance),
                candidates=candidates,
                steps=min(steps, model.schedule.num_steps),
                local_attention=not self.dense,
                **paper,
            )
        return simulate(scenario, policy, config).rollouts


def _int_option(settings: dict[str, str], key: str) -> int | None:
    """`settings[key]` as an integer (None when absent), or a one-line InputError."""
    if key not in settings:
        return None
    try:
        return int(settings[key])
    except ValueError:
        raise InputError(f"{key} must be an integer, got {settings[key]!r}", where="--method") from None


def windows_of(labels_dir: str, split: str, limit: int | None) -> list[Scenario]:
    """Windows of a dataset split that log the 8 s the metrics score (at most `limit`, in dataset order)."""
    found = []
    for record in held_out_records(labels_dir, split):
        if limit is not None and len(found) >= limit:
            break
        scenario = load_window(record)
        if scenario.num_steps - scenario.current_index - 1 >= FUTURE_STEPS:
            found.append(scenario)
    return found


def score(scenario: Scenario, rollouts: Rollouts) -> dict[str, float]:
    """One window's figures (offroad: NaN for a map without road edges or a scene without vehicles)."""
    wosac = evaluate_scenario(scenario, rollouts, "2025")
    scene_map = SceneMap.from_scenario(scenario)
    out = {
        "meta": wosac.metametric,
        "kinematic": wosac.kinematic_metrics,
        "interactive": wosac.interactive_metrics,
        "map": wosac.map_based_metrics,
        "offroad": math.nan,
        "collision": collision_rate(scenario, rollouts),
    }
    if scene_map.road_edges is not None:
        with contextlib.suppress(InputError):  # no vehicle among the sim agents
            out["offroad"] = offroad_rate(scenario, rollouts, scene_map=scene_map)
    return out


def _nanmean(values: Sequence[float]) -> float:
    finite = [v for v in values if not math.isnan(v)]
    return float(np.mean(finite)) if finite else math.nan


def realism_table(
    methods: Sequence[Method],
    scenes: Sequence[Scenario],
    config: SimConfig,
    candidates: int,
    steps: int,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """Mean figures per method over `scenes`, the per-window figures, and seconds per simulation."""
    table, per_window = {}, {}
    for method in methods:
        rows, seconds = [], []
        for scenario in scenes:
            begin = time.perf_counter()
            rollouts = method.rollouts(scenario, config, candidates, steps)
            seconds.append(time.perf_counter() - begin)
            rows.append(score(scenario, rollouts) | {"scenario_id": scenario.scenario_id})
        per_window[method.name] = rows
        table[method.name] = {c: _nanmean([r[c] for r in rows]) for c in COLUMNS} | {
            "min_meta": min(r["meta"] for r in rows),
            "windows": len(rows),
            "seconds_per_simulation": float(np.median(seconds)),
        }
        if progress:
            progress(f"  {method.name}: meta {table[method.name]['meta']:.3f} ({len(rows)} windows)")
    return {"table": table, "per_window": per_window}


def markdown(table: dict[str, dict[str, float]]) -> str:
    """The table as Markdown (NaN as a dash)."""

    def cell(v: float) -> str:
        return "–" if math.isnan(v) else f"{v:.3f}"

    lines = [
        "| method | meta | kinematic | interactive | map | offroad | collision | lowest meta | s per simulation |",
        "|" + " --- |" * 9,
    ]
    for name, r in table.items():
        figures = [cell(r[c]) for c in COLUMNS] + [cell(r["min_meta"]), f"{r['seconds_per_simulation']:.1f}"]
        lines.append(f"| {name} | " + " | ".join(figures) + " |")
    return "\n".join(lines)


def realism_experiment(
    methods: Sequence[str],
    datasets: Sequence[str],
    *,
    windows: int | None = None,
    candidates: int = 4,
    steps: int = 5,
    seed: int = 0,
    json_out: str | Path | None = None,
) -> dict[str, dict]:
    """The realism table of every dataset (`NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]]`, default split val and 8
    rollouts), printed as Markdown and written to `json_out` when given."""
    parsed = [Method.parse(m) for m in methods]
    loaded = [m.load() for m in parsed]
    results = {}
    for item in datasets:
        spec = DatasetSpec.parse(item)
        name, folder, rollouts = spec.name, spec.folder, spec.rollouts or 8
        scenes = windows_of(folder, spec.split, windows)
        if not scenes:
            raise InputError("no window logs 8 s after its current step", path=folder)
        print(f"\n{name}: {len(scenes)} windows, {rollouts} rollouts, {candidates} candidates per replan, K = {steps}")
        result = realism_table(loaded, scenes, SimConfig(rollouts=rollouts, seed=seed), candidates, steps, print)
        results[name] = result | {"rollouts": rollouts}
        print(markdown(result["table"]))
    if json_out:
        with atomic_path(json_out) as tmp:
            tmp.write_text(json.dumps(results, indent=1, default=float))
    return results
