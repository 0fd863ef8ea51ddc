"""Where the realism table's offroad and collisions come from (issue 45): every off-road and collision event of
each method's closed-loop rollouts, sorted by cause (`sim.failures`), with the log's own events as the floor, one
table per dataset and one per network kind of its synthesized windows.

    langtraj experiment failures --method NAME=SPEC ... --data NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]] ... \\
        [--windows N] [--rollouts R] [--candidates M] [--seed S] [--no-floor] [--json OUT]
    langtraj experiment failures --config configs/experiments/failures-heldout-maps.yaml   # the same as YAML

The methods are the realism table's (`experiments.realism.Method`, the same specs), each driving every sim agent
without text. A row's figures are means over the windows (each window weighs the same, as in the realism table):
`offroad` and `collision` (the realism table's shares of (rollout, vehicle) and (rollout, agent) pairs) and their
parts per cause (`offroad:CAUSE`, `collision:CAUSE`); `offroad:no_road_edges` is the share of vehicle pairs that
could not be measured. The row "log (reads the future)" is the logged future replayed as one rollout
(`sim.failures.log_breakdown`): what the log's own paths and boxes give, the floor (it reads the future, so it is
no simulation). A synthesized window's network kind is its metadata's `kind` (else its id's, `scenario.ids`);
windows of real scenes report under their dataset's name.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from langtraj.errors import InputError
from langtraj.experiments.base import EXPERIMENTS, Experiment
from langtraj.experiments.common import nanmean, window_kind
from langtraj.experiments.realism import Method, RealismSettings, breakdown_markdown, dataset_windows
from langtraj.scenario.model import Scenario
from langtraj.sim.config import SimConfig
from langtraj.sim.failures import BREAKDOWN_KEYS, FailureScene, classify_failures, log_rollouts
from langtraj.sim.policies import LoadedModel

LOG_ROW = "log (reads the future)"
"""The name of the floor's row."""
FIGURES = ("offroad", "collision", *BREAKDOWN_KEYS)
"""A row's figures, each a mean over its windows."""


def _mean_row(rows: Sequence[dict]) -> dict[str, float]:
    return {k: nanmean([r[k] for r in rows]) for k in FIGURES} | {"windows": len(rows)}


def failures_table(
    methods: Sequence[Method],
    scenes: Sequence[Scenario],
    kinds: Sequence[str],
    config: SimConfig,
    candidates: int,
    steps: int,
    loaded: Mapping[str, LoadedModel | None],
    *,
    floor: bool = True,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """Per method (and, with `floor`, the log as `LOG_ROW`): the mean figures over `scenes` (`table`), the same per
    window kind (`by_kind`, `kinds[i]` being scene i's) and per window, with every event (`per_window`)."""
    causes = [FailureScene.build(scenario) for scenario in scenes]  # once for every method
    table: dict[str, dict] = {}
    by_kind: dict[str, dict[str, dict]] = {kind: {} for kind in dict.fromkeys(kinds)}
    per_window: dict[str, list[dict]] = {}
    rows_of = [(m.name, m) for m in methods] + ([(LOG_ROW, None)] if floor else [])
    for name, method in rows_of:
        rows = []
        for scenario, scene, kind in zip(scenes, causes, kinds, strict=True):
            if method is None:
                rollouts = log_rollouts(scenario)
            else:
                rollouts = method.rollouts(scenario, config, candidates, steps, loaded[method.name])
            report = classify_failures(scenario, rollouts, scene=scene)
            figures = {"offroad": report.offroad_rate, "collision": report.collision_rate} | report.shares()
            rows.append(figures | {"scenario_id": scenario.scenario_id, "kind": kind, "report": report})
        table[name] = _mean_row(rows)
        for kind in by_kind:
            of_kind = [r for r in rows if r["kind"] == kind]
            by_kind[kind][name] = _mean_row(of_kind)
        per_window[name] = [
            {k: v for k, v in r.items() if k != "report"} | {"events": [e.to_dict() for e in r["report"].events]}
            for r in rows
        ]
        if progress:
            row = table[name]
            progress(f"  {name}: offroad {row['offroad']:.3f}, collision {row['collision']:.3f} ({len(rows)} windows)")
    return {"table": table, "by_kind": by_kind, "per_window": per_window}


@dataclass(frozen=True, kw_only=True)
class FailuresSettings(RealismSettings):
    """The failure table's settings: the realism table's rows and simulation settings (`RealismSettings`), and
    whether the log's own row is added (`floor`)."""

    floor: bool = True

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.floor and any(m.name == LOG_ROW for m in self.methods):
            raise InputError(f"{LOG_ROW!r} names the log's own row", where="--method")


@EXPERIMENTS.register
class FailuresExperiment(Experiment):
    """`langtraj experiment failures`: each method's off-road and collision events by cause, per dataset and per
    network kind, beside the log's own."""

    name = "failures"
    settings = FailuresSettings

    def tables(self, settings: FailuresSettings) -> dict[str, dict]:
        loaded = {m.name: m.load() for m in settings.methods}  # once for every dataset
        results = {}
        for spec in settings.datasets:
            scenes, config = dataset_windows(spec, settings)
            kinds = [window_kind(scenario, spec.name) for scenario in scenes]
            result = failures_table(
                settings.methods,
                scenes,
                kinds,
                config,
                settings.candidates,
                settings.steps,
                loaded,
                floor=settings.floor,
                progress=print,
            )
            results[spec.name] = result | {"rollouts": config.rollouts}
            print(breakdown_markdown(result["table"]))
            if set(kinds) != {spec.name}:  # synthesized windows: one table per network kind
                print(f"\n{spec.name} by network kind (windows in brackets):")
                rows = {
                    f"{kind} ({next(iter(per.values()))['windows']}): {name}": row
                    for kind, per in sorted(result["by_kind"].items())
                    for name, row in per.items()
                }
                print(breakdown_markdown(rows))
        return results
