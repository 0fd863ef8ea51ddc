"""What the experiments share (docs/experiments.md): the datasets they read (`DatasetSpec`), the one choice of
held-out windows, `NAME=VALUE` shorthands, NaN-aware means, Markdown tables and the JSON of their figures."""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.interdrive.dataset import SPLITS, WindowRecord, in_split, iter_records, load_window
from langtraj.metrics.controllability import collision_rate, offroad_rate
from langtraj.metrics.features import SceneMap
from langtraj.metrics.wosac import evaluate_scenario
from langtraj.model.config import SampleConfig
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.ids import SYNTH_ID
from langtraj.scenario.model import Scenario
from langtraj.training.data import SceneDataset


def parse_named(item: str, where: str, form: str = "NAME=VALUE") -> tuple[str, str]:
    """`NAME=VALUE` as (name, value); a missing name or value is a one-line InputError at `where`."""
    name, sep, value = item.partition("=")
    if not sep or not name or not value:
        raise InputError(f"expected {form}, got {item!r}", where=where)
    return name, value


@dataclass(frozen=True)
class DatasetSpec:
    """A dataset an experiment scores: its name in the tables, its InterDrive labels folder, the split of its
    windows (`interdrive.dataset.SPLITS`, default the held-out val) and, for the closed-loop tables, its own
    rollouts per window (None: the experiment's). Shorthand: `NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]]`."""

    name: str
    labels: Path
    split: str = "val"
    rollouts: int | None = None

    def __post_init__(self) -> None:
        if self.split not in SPLITS:
            raise InputError(f"split must be train, val or all, got {self.split!r}", where="--data")
        if self.rollouts is not None and self.rollouts < 1:
            raise InputError(f"rollouts must be >= 1, got {self.rollouts}", where="--data")

    @classmethod
    def parse(cls, item: str) -> DatasetSpec:
        name, rest = parse_named(item, "--data", "NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]]")
        folder, _, tail = rest.partition(":")
        split, _, count = tail.partition(":")
        try:
            rollouts = int(count) if count else None
        except ValueError:
            raise InputError(f"rollouts must be a whole number, got {count!r}", where="--data") from None
        return cls(name, Path(folder), split or "val", rollouts)


@dataclass(frozen=True, kw_only=True)
class SimulationSettings:
    """What every closed-loop table sets: the datasets, at most `windows` windows of each, `rollouts` per window (a
    dataset's own, when it gives them), `candidates` per replan, `steps` denoising steps (at most a model's K), the
    seed, and where to write every figure (None: nowhere)."""

    datasets: tuple[DatasetSpec, ...]
    windows: int | None = None
    rollouts: int = 8
    candidates: int = 4
    steps: int = 5
    seed: int = 0
    json: Path | None = None

    def __post_init__(self) -> None:
        require_items(self.datasets, "--data")
        require_counts(self, ("windows", "rollouts", "candidates", "steps"))


def held_out_windows(spec: DatasetSpec, skip: int = 0) -> Iterator[tuple[WindowRecord, Scenario]]:
    """The windows of the spec's split (`interdrive.dataset.in_split`, as training holds them out) in dataset
    order after the first `skip`, each with its record, loaded one at a time (a missing scenario file is a
    one-line InputError)."""
    records = [r for _, shard in iter_records(spec.labels) for r in shard if in_split(r, spec.split)]
    for record in records[skip:]:
        try:
            yield record, load_window(record)
        except FileNotFoundError:
            raise InputError("scenario file not found", path=record.source) from None


def held_out_dataset(
    data: SampleConfig,
    labels_dir,
    *,
    split: str = "val",
    seed: int = 0,
    label_fraction: float | None = None,
    decision_first: bool | None = None,
) -> SceneDataset:
    """The windows of `split` as samples of a model trained with `data`, each with its ground-truth prompt:
    no text or history dropout. `label_fraction` (default: the training setting) is the share of the
    other labelled agents given a single-agent sentence beside an interaction prompt's agents;
    `decision_first` (default: the training setting) gives it first to the agents that decide after the current
    step (`SampleConfig.decision_first`)."""
    data = data.for_inference(text=True)
    if label_fraction is not None:
        data = replace(data, heuristic_label_fraction=label_fraction)
    if decision_first is not None:
        data = replace(data, decision_first=decision_first)
    return SceneDataset(labels_dir, data, split=split, seed=seed, augment=False)


def require_counts(settings: Any, names: Sequence[str], minimum: int = 1) -> None:
    """Each of the `names` settings (None: no limit) is at least `minimum`; an error names the flag."""
    for name in names:
        value = getattr(settings, name)
        if value is not None and value < minimum:
            raise InputError(f"must be >= {minimum}, got {value}", where=f"--{name.replace('_', '-')}")


def require_items(items: Sequence[Any], flag: str) -> None:
    """At least one item (dataset, method, checkpoint), none of whose names repeats; an error names the flag."""
    if not items:
        raise InputError("give at least one", where=flag)
    names = [item.name for item in items]
    if len(set(names)) < len(names):
        raise InputError(f"names repeat: {names}", where=flag)


def wosac_figures(scenario: Scenario, rollouts: Rollouts, scene_map: SceneMap) -> dict[str, float]:
    """One window's WOSAC 2025 meta-metric and its kinematic, interactive and map-based buckets."""
    wosac = evaluate_scenario(scenario, rollouts, "2025", scene_map=scene_map)
    return {
        "meta": wosac.metametric,
        "kinematic": wosac.kinematic_metrics,
        "interactive": wosac.interactive_metrics,
        "map": wosac.map_based_metrics,
    }


def safety_figures(scenario: Scenario, rollouts: Rollouts, scene_map: SceneMap) -> dict[str, float]:
    """One window's share of (rollout, sim agent) pairs that collide and of (rollout, vehicle) pairs that leave the
    road (offroad: NaN for a map without road edges or a scene without vehicles)."""
    out = {"collision": collision_rate(scenario, rollouts), "offroad": math.nan}
    if scene_map.road_edges is not None:
        with contextlib.suppress(InputError):  # no vehicle among the sim agents
            out["offroad"] = offroad_rate(scenario, rollouts, scene_map=scene_map)
    return out


def nanmean(values: Sequence[float]) -> float:
    """The mean of the values that are not NaN (NaN when none is)."""
    finite = [v for v in values if not math.isnan(v)]
    return float(np.mean(finite)) if finite else math.nan


def cell(value: float | None) -> str:
    """A table figure to three decimals; NaN or None as a dash."""
    return "–" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.3f}"


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A Markdown table of already formatted cells."""
    lines = ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def write_results(path: str | Path | None, results: dict[str, Any]) -> None:
    """Every figure of an experiment as JSON at `path` (nothing when None), written whole or not at all."""
    if path:
        with atomic_path(path) as tmp:
            tmp.write_text(json.dumps(results, indent=1, default=float))


def window_kind(scenario: Scenario, dataset: str) -> str:
    """The network kind of a synthesized window (its metadata's `kind`, else the kind its id names), else `dataset`."""
    kind = scenario.metadata.get("kind")
    if isinstance(kind, str) and kind:
        return kind
    match = SYNTH_ID.match(scenario.scenario_id)
    return match["run"].rsplit("-", 1)[0] if match else dataset
