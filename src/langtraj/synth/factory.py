"""The scenario factory: plans (kind, seed) shards, runs them on an executor, writes a manifest.

Each kind gets an equal share of the requested windows. Shards are planned in rounds: a round asks
each kind that is still short for enough shards of at most `windows_per_shard` windows; a shard that
yields fewer (windows are filtered) is made up for by the next round. Shard seeds depend only on the run
seed, the kind and the shard index, so the plan and every shard are the same whatever the worker count.
A shard whose file and sidecar exist with the same seed, quota and settings is not run again (resume).
Shards are written zstd-compressed (`kind-0000.tfrecord.zst`) unless `compress` is off; a resumed
shard counts as finished under either name, since compression does not change what it holds.

See docs/data.md.
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from langtraj import __version__
from langtraj.executors import EXECUTORS
from langtraj.fileio import ZSTD_SUFFIX, atomic_open, read_json
from langtraj.synth.shard import ShardConfig, ShardOutcome, ShardTask, run_shard, shard_seed
from langtraj.synth.sumo import SynthError, sumo_version

MAX_ROUNDS = 8
"""Rounds of shards before giving up on a kind that keeps yielding too few windows."""


@dataclass(frozen=True)
class FactoryConfig:
    """A synthesis job: which kinds, how many windows in all, the seed, the output, and where shards run
    (`executor` "process" or "ray", with at most `workers` shards at once). `compress` writes each shard as
    one zstd frame, about 10x smaller: every window of a shard repeats the same road map."""

    kinds: tuple[str, ...]
    windows: int
    seed: int
    out: Path
    workers: int = 1
    executor: str = "process"
    windows_per_shard: int = 40
    shard: ShardConfig = field(default_factory=ShardConfig)
    compress: bool = True

    def targets(self) -> dict[str, int]:
        """Windows per kind: an equal share, the remainder to the first kinds."""
        base, extra = divmod(self.windows, len(self.kinds))
        return {kind: base + (1 if i < extra else 0) for i, kind in enumerate(self.kinds)}


def shard_path(out: Path, kind: str, index: int, compress: bool = True) -> Path:
    """Where shard `index` of `kind` goes: `out/shards/kind-0000.tfrecord`, plus `.zst` when compressed."""
    return out / "shards" / f"{kind}-{index:04d}.tfrecord{ZSTD_SUFFIX if compress else ''}"


def _shard_file(task: ShardTask) -> Path | None:
    """The task's shard file on disk: under its own name, else under the other naming (compressed or not),
    so that a corpus resumes whichever way it was written; None when there is neither."""
    return next((p for p in (task.path, task.other_path) if p.is_file()), None)


def _finished(task: ShardTask, config: ShardConfig) -> ShardOutcome | None:
    """The sidecar of a finished shard with the same seed, quota and settings (and its file under either
    naming, unless it has no windows), else None."""
    if not task.stats_path.exists():
        return None
    try:
        data = json.loads(task.stats_path.read_text())
        outcome = ShardOutcome(**data)
    except (OSError, ValueError, TypeError):
        return None
    if (outcome.seed, outcome.quota, outcome.settings) != (
        task.seed,
        task.quota,
        json.loads(json.dumps(asdict(config))),
    ):
        return None
    if not outcome.windows:
        return outcome
    if (found := _shard_file(task)) is None:
        return None
    return replace(outcome, file=found.name, bytes=found.stat().st_size)  # older sidecars have neither


def _run_task(args: tuple[ShardTask, ShardConfig]) -> ShardOutcome:
    task, config = args
    return run_shard(task, config)


def _round_tasks(config: FactoryConfig, short: dict[str, int], next_index: dict[str, int]) -> list[ShardTask]:
    tasks = []
    for kind, missing in short.items():
        for _ in range(math.ceil(missing / config.windows_per_shard)):
            index = next_index[kind]
            next_index[kind] += 1
            quota = min(config.windows_per_shard, missing)
            missing -= quota
            seed = shard_seed(config.seed, kind, index)
            tasks.append(ShardTask(kind, index, seed, quota, shard_path(config.out, kind, index, config.compress)))
    return tasks


def read_factory_manifest(out: Path) -> dict[str, Any]:
    """The manifest `run_factory` wrote into corpus folder `out`; a missing or unreadable one raises InputError."""
    return read_json(Path(out) / "manifest.json", "no manifest.json: not a finished corpus (langtraj synth)")


def run_factory(config: FactoryConfig, progress: bool = True) -> dict[str, Any]:
    """Run (or resume) a synthesis job; returns the manifest it writes to `out/manifest.json`."""
    from tqdm import tqdm

    if config.windows < 1:
        raise SynthError("--windows must be at least 1")
    (config.out / "shards").mkdir(parents=True, exist_ok=True)  # fail before simulating, not after
    targets = config.targets()
    produced = dict.fromkeys(config.kinds, 0)
    next_index = dict.fromkeys(config.kinds, 0)
    outcomes: list[ShardOutcome] = []  # in completion order; the manifest sorts them
    executor = EXECUTORS.create(config.executor, where="--executor")
    bar = tqdm(total=config.windows, unit="win", disable=not progress, desc="synth")

    def record(outcome: ShardOutcome) -> None:
        outcomes.append(outcome)
        produced[outcome.kind] += outcome.windows
        bar.update(outcome.windows)

    try:
        for _ in range(MAX_ROUNDS):
            short = {k: targets[k] - produced[k] for k in config.kinds if produced[k] < targets[k]}
            if not short:
                break
            tasks = _round_tasks(config, short, next_index)
            pending = []
            for task in tasks:
                done = _finished(task, config.shard)
                if done is None:
                    pending.append((task, config.shard))
                else:
                    record(done)
            for outcome in executor.map(_run_task, pending, config.workers):
                record(outcome)
    finally:
        bar.close()
    manifest = build_manifest(config, outcomes, targets)
    with atomic_open(config.out / "manifest.json", "w") as fh:
        fh.write(json.dumps(manifest, indent=1, sort_keys=True))
    missing = [k for k in config.kinds if produced[k] < targets[k]]
    if missing:
        raise SynthError(
            f"after {MAX_ROUNDS} rounds of shards these kinds are still short of windows: {', '.join(missing)} "
            f"(see {config.out / 'manifest.json'}, rejections per kind)"
        )
    return manifest


def _distribution(values: Iterable[int]) -> dict[str, float]:
    arr = np.asarray(list(values), np.float64)
    if arr.size == 0:
        return {"count": 0}
    return {
        "count": int(arr.size),
        "min": float(arr.min()),
        "median": float(np.median(arr)),
        "mean": round(float(arr.mean()), 2),
        "max": float(arr.max()),
    }


def build_manifest(config: FactoryConfig, outcomes: Sequence[ShardOutcome], targets: dict[str, int]) -> dict[str, Any]:
    """Counts per kind, agents per window, event and rejection counts, bytes on disk, seeds, versions and
    shard list."""
    per_kind: dict[str, Any] = {}
    ordered = sorted(outcomes, key=lambda o: (o.kind, o.index))
    for kind in config.kinds:
        mine = [o for o in ordered if o.kind == kind]
        per_kind[kind] = {
            "target": targets[kind],
            "windows": sum(o.windows for o in mine),
            "shards": len(mine),
            "agents_per_window": _distribution(a for o in mine for a in o.agents_per_window),
            "agent_types": dict(sum((Counter(o.agent_types) for o in mine), Counter())),
            "events": dict(sum((Counter(o.events) for o in mine), Counter())),
            "decisions": dict(sum((Counter(o.decisions) for o in mine), Counter())),
            "windows_with_decision_ahead": sum(o.decisions_ahead for o in mine),
            "rejections": dict(sum((Counter(o.rejections) for o in mine), Counter())),
            "sumo_collisions": sum(o.collisions for o in mine),
            "sumo_teleports": sum(o.teleports for o in mine),
            "simulation_seconds": round(sum(o.seconds for o in mine), 2),
            "bytes_per_window": round(sum(o.bytes for o in mine) / max(sum(o.windows for o in mine), 1)),
        }
    return {
        "langtraj_version": __version__,
        "sumo_version": sumo_version(),
        "seed": config.seed,
        "kinds": list(config.kinds),
        "windows": sum(o.windows for o in ordered),
        "config": {
            "windows_per_shard": config.windows_per_shard,
            "duration_s": "auto" if config.shard.duration_s is None else config.shard.duration_s,
            "window": json.loads(json.dumps(asdict(config.shard.window))),
        },
        "per_kind": per_kind,
        "shards": [
            {
                "file": str(Path("shards") / o.file),
                "kind": o.kind,
                "index": o.index,
                "seed": o.seed,
                "windows": o.windows,
                "bytes": o.bytes,
            }
            for o in ordered
            if o.windows
        ],
        "empty_shards": sum(1 for o in ordered if not o.windows),
    }
