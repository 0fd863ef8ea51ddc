"""The feature store: every window's `scene_sample` arrays computed once, then read back by training as
memory-mapped arrays, so a training sample costs a copy instead of a window decode and a map selection
(docs/model.md, 'The feature store').

A store folder holds `store.json` (the features key it was built for, its chunks and their row counts)
and one folder per chunk: `index.jsonl` (one `WindowRecord` per row with its prompts, which training
draws sentences from, but not its labels, which it never reads; and the row's deciders) and one
`FIELD.npy` per `SAMPLE_ARRAYS` and `TARGET_ARRAYS` field, [rows, ...]: the samples, and the target actions
their futures ask for (`model.targets`), fitted once here instead of at every training step. A store is
built from an InterDrive labels folder (`labelled_jobs`: every stage) or straight from scenario files without
labels (`scenario_jobs`: stage 1 needs none). `build_store` writes each chunk into `STORE.partial/` as a whole
(temporary folder, then rename), so a killed build resumes with the chunks not yet done, provided it was planned
from the same windows (`_plan`: every chunk's windows, in order, as its index stores them; or its files); the folder
becomes STORE only when every chunk is there.
"""

from __future__ import annotations

import bisect
import hashlib
import itertools
import json
import os
import shutil
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.executors import EXECUTORS
from langtraj.fileio import atomic_path
from langtraj.interdrive.dataset import WindowRecord, file_windows, iter_records, load_window, window_record
from langtraj.interdrive.labels import WindowLabels
from langtraj.model.config import SampleConfig
from langtraj.model.features import SAMPLE_ARRAYS, features_key, sample_of, scene_sample
from langtraj.model.targets import TARGET_ARRAYS, stored_targets
from langtraj.scenario.model import Scenario
from langtraj.scenario.selection import deciders

STORE_FILE = "store.json"
INDEX_FILE = "index.jsonl"
FEATURES_FOLDER = "features"
"""Where a labels folder keeps its stores: LABELS/features/<digest of the features key>/."""

CHUNK_WINDOWS = 256
"""Windows per build job from a labels folder: small enough to resume often, large enough to keep a worker busy."""

CHUNK_FILES = 8
"""Scenario files per build job from scenario files (a synthesized shard holds up to 40 windows)."""

_STORED_DTYPES: dict[str, type[np.generic]] = {"agent_type": np.int8, "map_type": np.int8}
"""Fields stored narrower than the sample holds them (exact: type enums fit in int8)."""

STORED_ARRAYS: dict[str, type[np.generic]] = SAMPLE_ARRAYS | TARGET_ARRAYS
"""Every array of a stored row, with the dtype a sample holds it in."""


def store_digest(config: SampleConfig) -> str:
    """A short name for `features_key(config)`: the folder of a labels folder's store for that config."""
    return hashlib.sha256(json.dumps(features_key(config), sort_keys=True).encode()).hexdigest()[:12]


def default_store_path(labels_dir: str | Path, config: SampleConfig) -> Path:
    """LABELS/features/<digest>: where `langtraj features build` puts a labels folder's store."""
    return Path(labels_dir) / FEATURES_FOLDER / store_digest(config)


def is_store(path: str | Path) -> bool:
    """Whether `path` is a finished feature store folder."""
    return (Path(path) / STORE_FILE).is_file()


def record_key(record: WindowRecord) -> tuple[str, int, int]:
    """What identifies a window across a labels folder and a store: its file, scene and start step."""
    return record.source, record.record, record.window_start


# ---------------------------------------------------------------- reading


@dataclass(frozen=True)
class StoreRow:
    """One row's record and deciders (track ids that carry out a decision after the current step)."""

    record: WindowRecord
    deciders: frozenset[int]


class FeatureStore:
    """A finished store, opened read-only: `rows` from the chunk indexes, arrays memory-mapped on first use
    (a store pickles without its maps into DataLoader workers, each mapping the files itself)."""

    def __init__(
        self, path: str | Path, config: SampleConfig | None = None, *, rows: Sequence[Sequence[StoreRow]] | None = None
    ) -> None:
        """`rows`: each chunk's rows when the caller has them already (`build_store`), else read from the indexes."""
        self.path = Path(path)
        meta_path = self.path / STORE_FILE
        try:
            self.meta = json.loads(meta_path.read_text())
            self.chunks: tuple[str, ...] = tuple(c["folder"] for c in self.meta["chunks"])
            counts = [int(c["windows"]) for c in self.meta["chunks"]]
        except FileNotFoundError:
            raise InputError("not a feature store (no store.json; langtraj features build)", path=self.path) from None
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed: {exc!r}", path=meta_path) from None
        if config is not None and self.meta.get("key") != features_key(config):
            raise InputError(
                f"built for other sample settings ({_difference(self.meta.get('key'), features_key(config))}); "
                "rebuild it with langtraj features build",
                path=meta_path,
                where="key",
            )
        self.starts = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        if rows is None:
            rows = [list(_read_index(self.path / folder / INDEX_FILE)) for folder in self.chunks]
        for folder, count, chunk_rows in zip(self.chunks, counts, rows, strict=True):
            if len(chunk_rows) != count:
                raise InputError(f"{len(chunk_rows)} rows, store.json says {count}", path=self.path / folder)
        self.rows: tuple[StoreRow, ...] = tuple(itertools.chain.from_iterable(rows))
        self._maps: dict[int, dict[str, np.ndarray]] = {}

    def __len__(self) -> int:
        return len(self.rows)

    def _chunk_arrays(self, number: int) -> dict[str, np.ndarray]:
        arrays = self._maps.get(number)
        if arrays is None:
            arrays = {}
            for name in STORED_ARRAYS:
                file = self.path / self.chunks[number] / f"{name}.npy"
                try:
                    arrays[name] = np.load(file, mmap_mode="r")
                except (OSError, ValueError) as exc:
                    raise InputError(f"cannot map: {exc}", path=file) from None
            self._maps[number] = arrays
        return arrays

    def sample(self, row: int) -> dict[str, Any]:
        """Row `row` as a fresh `scene_sample` dict (own arrays, no text, not interaction-labelled) with its
        target actions (`TARGET_ARRAYS`)."""
        if not 0 <= row < len(self.rows):
            raise IndexError(f"row {row} of a store of {len(self.rows)}")
        number = bisect.bisect_right(self.starts, row) - 1
        arrays, offset = self._chunk_arrays(number), row - int(self.starts[number])
        own = {name: np.array(arrays[name][offset], dtype) for name, dtype in STORED_ARRAYS.items()}
        return sample_of(own, self.rows[row].record.scenario_id)

    def rows_by_key(self) -> dict[tuple[str, int, int], int]:
        """Row of each window, by `record_key`."""
        return {record_key(r.record): i for i, r in enumerate(self.rows)}

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_maps"] = {}
        return state


def _difference(stored: Any, wanted: dict[str, Any]) -> str:
    if not isinstance(stored, dict):
        return "no key"
    diffs = [f"{k} {stored.get(k)!r} != {v!r}" for k, v in wanted.items() if stored.get(k) != v]
    return ", ".join(diffs) or "same key"


def _read_index(path: Path) -> Iterator[StoreRow]:
    try:
        lines = path.read_text().splitlines()
    except FileNotFoundError:
        raise InputError("missing chunk index", path=path) from None
    for number, line in enumerate(lines, 1):
        try:
            obj = json.loads(line)
            record = WindowRecord.from_json(obj["record"], f"line {number}")
            yield StoreRow(record, frozenset(int(t) for t in obj["deciders"]))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed row: {exc!r}", path=path, where=f"line {number}") from None
        except InputError as exc:
            raise exc.located(path=path) from None


# ---------------------------------------------------------------- building


@dataclass(frozen=True)
class StoreJob:
    """One chunk to build: either given records (from a labels folder) or every window of some scenario
    files (no labels), with the sample settings."""

    number: int
    config: SampleConfig
    records: tuple[WindowRecord, ...] = ()
    files: tuple[str, ...] = ()

    @property
    def folder(self) -> str:
        return f"chunk-{self.number:05d}"

    def windows(self) -> Iterator[tuple[WindowRecord, Scenario]]:
        """(record, window) of every window of the job."""
        for record in self.records:
            try:
                yield record, load_window(record)
            except InputError as exc:
                raise exc.located(path=record.source, where=f"window {record.scenario_id}") from None
        for path in self.files:
            for number, start, window in file_windows(Path(path), None):
                yield window_record(window, path, number, start), window


def labelled_jobs(labels_dir: str | Path, config: SampleConfig) -> list[StoreJob]:
    """Jobs over every record of an InterDrive labels folder, `CHUNK_WINDOWS` records each, in manifest order."""
    records = [rec for _, shard in iter_records(Path(labels_dir)) for rec in shard]
    if not records:
        raise InputError("no window in the labels folder", path=labels_dir)
    return [
        StoreJob(n, config, records=tuple(records[i : i + CHUNK_WINDOWS]))
        for n, i in enumerate(range(0, len(records), CHUNK_WINDOWS))
    ]


def scenario_jobs(paths: Sequence[Path], config: SampleConfig) -> list[StoreJob]:
    """Jobs over every window of scenario files (`CHUNK_FILES` files each), without labels: stage 1's input
    without a label build. Windows are cut as a labels build with the default stride cuts them."""
    files = [str(Path(p).resolve()) for p in paths]
    if not files:
        raise InputError("no scenario file given")
    return [
        StoreJob(n, config, files=tuple(files[i : i + CHUNK_FILES]))
        for n, i in enumerate(range(0, len(files), CHUNK_FILES))
    ]


def _stored_record(record: WindowRecord) -> dict[str, Any]:
    """What a chunk's index keeps of a window's record: all but its labels (prompts stay; labels are the folder's)."""
    return replace(record, labels=WindowLabels(record.scenario_id)).to_json()


def _build_chunk(job: StoreJob, partial: Path) -> None:
    """Write one chunk folder (arrays and index) into `partial`, atomically."""
    samples, lines = [], []
    for record, window in job.windows():
        samples.append(scene_sample(window, job.config))
        lines.append(json.dumps({"record": _stored_record(record), "deciders": sorted(deciders(window))}))
    tmp = partial / f".{job.folder}.tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    targets = stored_targets(samples, job.config.dynamics) if samples else {}
    for name, dtype in STORED_ARRAYS.items():
        if name in targets:
            values = targets[name]
        else:
            values = np.stack([s[name] for s in samples]) if samples else np.zeros((0,), dtype)
        np.save(tmp / f"{name}.npy", values.astype(_STORED_DTYPES.get(name, dtype)))
    (tmp / INDEX_FILE).write_text("".join(line + "\n" for line in lines))
    os.replace(tmp, partial / job.folder)


def _run_job(item: tuple[StoreJob, Path]) -> None:
    _build_chunk(*item)


def _plan(jobs: Sequence[StoreJob]) -> str:
    """What a build of `jobs` makes, for a resumed build to compare: the features key and, per chunk, a digest of
    every window's record as its index will store it (id, file, scene, start step, agents, prompts; in order) and
    its scenario files. A chunk is reused only when its whole list of windows is the same, not merely its first
    window and count (a labels folder rebuilt since may hold other windows or prompts under the same first id)."""
    chunks = []
    for job in jobs:
        records = json.dumps([_stored_record(r) for r in job.records], sort_keys=True)
        chunks.append([len(job.records), hashlib.sha256(records.encode()).hexdigest(), list(job.files)])
    return json.dumps([features_key(jobs[0].config), chunks])


def build_store(
    jobs: Sequence[StoreJob],
    out: str | Path,
    *,
    workers: int = 1,
    executor: str = "process",
    say: Callable[[str], None] = print,
) -> FeatureStore:
    """Build the chunks of `jobs` into a store at `out`, resuming a killed build of the same jobs (chunks
    already in `out.partial/` are kept); returns it opened. A finished store at `out` is an error."""
    out = Path(out)
    if is_store(out):
        raise InputError("a feature store is already there (delete it to rebuild)", path=out)
    if not jobs:
        raise InputError("nothing to store", path=out)
    config = jobs[0].config
    partial = out.with_name(out.name + ".partial")
    plan = _plan(jobs)
    plan_file = partial / "plan.json"
    if partial.exists() and (not plan_file.is_file() or plan_file.read_text() != plan):
        shutil.rmtree(partial)  # an earlier build of other windows or settings: start over
    partial.mkdir(parents=True, exist_ok=True)
    with atomic_path(plan_file) as tmp:
        tmp.write_text(plan)
    todo = [(job, partial) for job in jobs if not (partial / job.folder / INDEX_FILE).is_file()]
    if len(todo) < len(jobs):
        say(f"feature store: resuming, {len(jobs) - len(todo)} of {len(jobs)} chunks done before")
    done = len(jobs) - len(todo)
    for _ in EXECUTORS.create(executor, where="--executor").map(_run_job, todo, workers):
        done += 1
        if done % 10 == 0 or done == len(jobs):
            say(f"feature store: {done} of {len(jobs)} chunks")
    # read from the chunks on disk (a resumed build did not make all of them), once: they count the rows too
    rows = [list(_read_index(partial / job.folder / INDEX_FILE)) for job in jobs]
    chunks = [{"folder": job.folder, "windows": len(r)} for job, r in zip(jobs, rows, strict=True)]
    meta = {"key": features_key(config), "chunks": chunks}
    with atomic_path(partial / STORE_FILE) as tmp:
        tmp.write_text(json.dumps(meta, indent=1))
    plan_file.unlink()
    os.replace(partial, out)
    return FeatureStore(out, config, rows=rows)
