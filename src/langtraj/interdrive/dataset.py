"""The InterDrive dataset on disk: per-window labels and prompt pools, sharded, with a manifest.

`build_dataset` labels every window of some scenario files (WOMD TFRecords, ScenarioNet pickles,
synthesized shards) and writes, into one folder, a JSON-lines shard per scenario file and
`manifest.json`. Scenarios stay where they are: each record names its file, record index and window
start. Scenes longer than one window (nuScenes, 20 s) are cut into 91-step windows first. A record
holds the single-agent labels (with the labels the heuristics could not decide), the interaction
labels by source (SUMO ground truth on synthesized scenes, the detector, humans), and the prompt pool
with each prompt's role-rephrased sentences. Reruns reuse shards whose input and settings match.

See docs/interdrive.md.
"""

from __future__ import annotations

import hashlib
import json
from collections import Counter
from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from langtraj import __version__
from langtraj.errors import InputError
from langtraj.executors import EXECUTORS
from langtraj.fileio import atomic_open, read_json
from langtraj.interdrive.detector import detect_interactions
from langtraj.interdrive.ground_truth import ground_truth_interactions
from langtraj.interdrive.heuristics import HeuristicConfig, label_agents
from langtraj.interdrive.labels import InteractionLabel, LabelSource, WindowLabels
from langtraj.interdrive.prompts import (
    TEMPLATES_ONLY,
    LLMConfig,
    LLMRephraser,
    PhraseBank,
    Prompt,
    build_prompt_pool,
    llm_phrase_bank,
    role_rephrase,
)
from langtraj.roads import MapIndex
from langtraj.scenario.ids import map_group
from langtraj.scenario.io import read_scenario, read_scenarios
from langtraj.scenario.model import Scenario
from langtraj.scenario.windowing import WindowSpec, cut_window, iter_windows

MANIFEST = "manifest.json"
LABELS_DIR = "labels"
FORMAT_VERSION = 1


@dataclass(frozen=True)
class BuildConfig:
    """Settings of a dataset build; a shard is reused only when they match."""

    seed: int = 0  # prompt sampling seed (each window's seed derives from it and the window id)
    prompts_per_agent: int = 3  # compositional prompts drawn per labelled agent
    detector: bool = True  # run the rule-based interaction detector (always on for scenes without events)
    window_stride: int | None = None  # steps between windows of long scenes (default: non-overlapping)
    heuristics: HeuristicConfig = field(default_factory=HeuristicConfig)
    llm_url: str | None = None  # an OpenAI-compatible endpoint adding LLM rephrasings to the phrase tables (off)
    llm_model: str = "gpt-4o-mini"

    def fingerprint(self) -> str:
        return hashlib.sha256(json.dumps(asdict(self), sort_keys=True, default=str).encode()).hexdigest()[:16]


@dataclass(frozen=True)
class PromptEntry:
    """One prompt of a window's pool: the `@id` text, the agents it mentions, and per mentioned agent the
    sentence in which that agent is "the target agent" (what the model is conditioned on)."""

    text: str
    mentions: tuple[int, ...]
    roles: Mapping[int, str]
    subtype: str | None
    labels: tuple[str, ...]
    source: str

    @classmethod
    def of(cls, prompt: Prompt) -> PromptEntry:
        roles = role_rephrase(prompt)
        return cls(
            prompt.text, tuple(prompt.mentions), roles, prompt.subtype_id, tuple(prompt.label_keys), prompt.source
        )

    def fits(self, agent_ids: Collection[int]) -> bool:
        """Whether every agent the prompt mentions is among `agent_ids`: a role sentence names the other
        mentioned agents ("other agent1", ...), so a prompt conditions a sample only whole."""
        ids = set(agent_ids)
        return bool(self.mentions) and all(m in ids and m in self.roles for m in self.mentions)

    def sentences(self, agent_ids: Sequence[int]) -> dict[int, str]:
        """Position in `agent_ids` -> role sentence, for every mentioned agent; empty unless the prompt `fits`."""
        if not self.fits(agent_ids):
            return {}
        position = {int(track): slot for slot, track in enumerate(agent_ids)}
        return {position[m]: self.roles[m] for m in self.mentions}

    def to_json(self) -> dict[str, Any]:
        return {
            "text": self.text,
            "mentions": list(self.mentions),
            "roles": {str(k): v for k, v in self.roles.items()},
            "subtype": self.subtype,
            "labels": list(self.labels),
            "source": self.source,
        }

    @classmethod
    def from_json(cls, obj: Mapping[str, Any]) -> PromptEntry:
        return cls(
            str(obj["text"]),
            tuple(int(m) for m in obj["mentions"]),
            {int(k): str(v) for k, v in obj["roles"].items()},
            obj.get("subtype"),
            tuple(obj.get("labels", ())),
            str(obj.get("source", "")),
        )


@dataclass(frozen=True)
class WindowRecord:
    """Labels and prompts of one window, and where its scenario is: `source` file, `record` index in
    it, and `window_start` step in that scene."""

    scenario_id: str
    source: str
    record: int
    window_start: int
    current_index: int
    num_steps: int
    track_ids: tuple[int, ...]
    labels: WindowLabels
    prompts: tuple[PromptEntry, ...] = ()

    def to_json(self) -> dict[str, Any]:
        return {
            "scenario_id": self.scenario_id,
            "source": self.source,
            "record": self.record,
            "window_start": self.window_start,
            "current_index": self.current_index,
            "num_steps": self.num_steps,
            "track_ids": list(self.track_ids),
            "labels": self.labels.to_json(),
            "prompts": [p.to_json() for p in self.prompts],
        }

    @classmethod
    def from_json(cls, obj: Mapping[str, Any], where: str) -> WindowRecord:
        try:
            return cls(
                str(obj["scenario_id"]),
                str(obj["source"]),
                int(obj["record"]),
                int(obj["window_start"]),
                int(obj["current_index"]),
                int(obj["num_steps"]),
                tuple(int(t) for t in obj["track_ids"]),
                WindowLabels.from_json(obj["labels"], where),
                tuple(PromptEntry.from_json(p) for p in obj.get("prompts", ())),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"malformed record: {exc!r}", where=where) from None


VAL_FRACTION = 0.1
"""The share of a dataset's scenes held out from training (the val split) unless a run says otherwise."""


def split_of(record: WindowRecord, val_fraction: float = VAL_FRACTION) -> str:
    """The split ("val" or "train") of a record, fixed by a hash of its map group (`scenario.ids.map_group`:
    the SUMO run of a synthesized window, the scene of a real one), so no road network and its traffic is on
    both sides."""
    key = map_group(record.scenario_id, record.window_start)
    value = int.from_bytes(hashlib.sha256(key.encode()).digest()[:8], "little") / 2.0**64
    return "val" if value < val_fraction else "train"


SPLITS = ("train", "val", "all")
"""Which of a dataset's windows a run reads: training's, the held-out ones (`split_of`), or every one."""


def in_split(record: WindowRecord, split: str, val_fraction: float = VAL_FRACTION) -> bool:
    """Whether `record` belongs to `split`, one of `SPLITS` (checked by the caller, once)."""
    return split == "all" or split_of(record, val_fraction) == split


# ---------------------------------------------------------------- labeling one window


def label_window(scenario: Scenario, config: BuildConfig = BuildConfig()) -> WindowLabels:
    """Every label of one window: heuristics, SUMO ground truth when the scene has events, the detector."""
    index = MapIndex.build(scenario.road_map)
    agent_labels, undecided = label_agents(scenario, config.heuristics, index)
    interactions: list[InteractionLabel] = []
    if scenario.events:
        interactions += ground_truth_interactions(scenario)
    if config.detector or not scenario.events:
        interactions += detect_interactions(scenario, agent_labels, map_index=index)
    return WindowLabels(scenario.scenario_id, tuple(agent_labels), tuple(undecided), tuple(interactions))


def phrase_bank(config: BuildConfig) -> PhraseBank:
    """The phrases prompts are drawn from: the templates, plus LLM rephrasings when `llm_url` is set
    (asked once per phrase and cached on disk)."""
    if config.llm_url is None:
        return TEMPLATES_ONLY
    return llm_phrase_bank(LLMRephraser(LLMConfig(url=config.llm_url, model=config.llm_model)))


def window_prompts(
    labels: WindowLabels, config: BuildConfig, bank: PhraseBank = TEMPLATES_ONLY
) -> tuple[PromptEntry, ...]:
    """The window's prompt pool, seeded by the build seed and the window id (same input, same prompts)."""
    digest = hashlib.sha256(f"{config.seed}:{labels.scenario_id}".encode()).digest()
    seed = int.from_bytes(digest[:8], "little")
    return tuple(PromptEntry.of(p) for p in build_prompt_pool(labels, seed, config.prompts_per_agent, bank))


def scene_windows(scenario: Scenario, spec: WindowSpec) -> Iterator[tuple[int, Scenario]]:
    """(start, window) pairs: the scene itself when it is one window long or shorter, else its windows."""
    if scenario.num_steps <= spec.length:
        yield 0, scenario
        return
    for window in iter_windows(scenario, spec):
        yield int(window.metadata["window"]["start"]), window


def window_record(
    window: Scenario,
    source: str | Path,
    record: int,
    start: int,
    labels: WindowLabels | None = None,
    prompts: tuple[PromptEntry, ...] = (),
) -> WindowRecord:
    """The record of `window` (scene `record` of file `source`, cut at step `start`); no labels when `labels` is
    None (what stage 1 trains on)."""
    return WindowRecord(
        window.scenario_id,
        str(Path(source).resolve()),
        record,
        start,
        window.current_index,
        window.num_steps,
        tuple(int(i) for i in window.agents.ids),
        WindowLabels(window.scenario_id, (), (), ()) if labels is None else labels,
        prompts,
    )


def file_windows(path: Path, stride: int | None) -> Iterator[tuple[int, int, Scenario]]:
    """(scene number, start, window) of every window with a future of every scene in one scenario file."""
    spec = WindowSpec(stride=stride)
    for record, scenario in enumerate(read_scenarios(path)):
        for start, window in scene_windows(scenario, spec):
            if window.current_index < window.num_steps - 1:  # else no future steps to label or learn
                yield record, start, window


def label_file(path: Path, config: BuildConfig, bank: PhraseBank = TEMPLATES_ONLY) -> list[WindowRecord]:
    """Records of every window of every scene in one scenario file."""
    records = []
    for record, start, window in file_windows(path, config.window_stride):
        labels = label_window(window, config)
        records.append(window_record(window, path, record, start, labels, window_prompts(labels, config, bank)))
    return records


# ---------------------------------------------------------------- shards and manifest


@dataclass(frozen=True)
class _ShardJob:
    source: Path
    target: Path
    config: BuildConfig
    bank: PhraseBank


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _run_job(job: _ShardJob) -> tuple[Path, dict[str, Any]]:
    """Label one scenario file into its shard; returns the source and the shard's counts."""
    try:
        records = label_file(job.source, job.config, job.bank)
    except InputError as exc:
        raise exc.located(path=job.source) from None
    records = _keep_human_labels(records, job.target, job.config, job.bank)
    write_shard(job.target, records)
    return job.source, {"windows": len(records), **_counts(records)}


def _keep_human_labels(
    records: list[WindowRecord], previous: Path, config: BuildConfig, bank: PhraseBank
) -> list[WindowRecord]:
    """`records` with the human labels the shard at `previous` held for the same windows (a rebuild must not
    lose imported labels)."""
    if not previous.is_file():
        return records
    human = {
        rec.scenario_id: [i for i in rec.labels.interactions if i.source is LabelSource.HUMAN]
        for rec in read_shard(previous)
    }
    return [
        with_human_labels(r, human[r.scenario_id], config, bank) if human.get(r.scenario_id) else r for r in records
    ]


def write_shard(path: Path, records: Sequence[WindowRecord]) -> None:
    """Write records as JSON lines, atomically."""
    with atomic_open(path, "w") as fh:
        for rec in records:
            fh.write(json.dumps(rec.to_json(), separators=(",", ":")) + "\n")


def read_shard(path: Path) -> list[WindowRecord]:
    """Records of one shard; a malformed line raises InputError naming the file and line."""
    records = []
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise InputError("no such labels shard", path=path) from None
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
        except json.JSONDecodeError as exc:
            raise InputError(f"not JSON: {exc.msg}", path=path, where=f"line {number}") from None
        records.append(_record(obj, path, number))
    return records


def _record(obj: Any, path: Path, number: int) -> WindowRecord:
    try:
        return WindowRecord.from_json(obj, f"line {number}")
    except InputError as exc:
        raise exc.located(path=path) from None


def _counts(records: Sequence[WindowRecord]) -> dict[str, Any]:
    interactions: Counter[str] = Counter()
    labels: Counter[str] = Counter()
    for rec in records:
        interactions.update(f"{i.source.value}:{i.subtype.id}" for i in rec.labels.interactions)
        labels.update(lab.key for lab in rec.labels.agent_labels)
    return {
        "interactions": dict(sorted(interactions.items())),
        "agent_labels": dict(sorted(labels.items())),
        "prompts": sum(len(r.prompts) for r in records),
    }


def read_manifest(out: Path) -> dict[str, Any]:
    """The dataset's manifest; a missing or unreadable one raises InputError naming it."""
    return read_json(
        Path(out) / MANIFEST, f"no {MANIFEST}: not an InterDrive dataset folder (run langtraj interdrive build)"
    )


def write_manifest(out: Path, manifest: Mapping[str, Any]) -> None:
    with atomic_open(Path(out) / MANIFEST, "w") as fh:
        json.dump(manifest, fh, indent=1, sort_keys=True)


def iter_records(out: Path) -> Iterator[tuple[Path, list[WindowRecord]]]:
    """(shard path, records) of every shard the manifest lists."""
    for shard in read_manifest(out)["shards"]:
        path = Path(out) / shard["file"]
        yield path, read_shard(path)


def build_dataset(
    sources: Sequence[Path], out: Path, config: BuildConfig = BuildConfig(), workers: int = 1, executor: str = "process"
) -> dict[str, Any]:
    """Label every window of `sources` into `out` (one shard per file) and write the manifest."""
    out = Path(out)
    sources = [Path(s) for s in sources]
    seen: set[Path] = set()
    for src in sources:
        if not src.is_file():
            raise InputError("no such scenario file", path=src)
        if src.resolve() in seen:
            raise InputError("listed twice", path=src)
        seen.add(src.resolve())
    previous = _previous_shards(out)
    fingerprint = config.fingerprint()
    bank = phrase_bank(config)
    entries: dict[int, dict[str, Any]] = {}
    jobs: list[tuple[int, _ShardJob, dict[str, Any]]] = []
    for number, src in enumerate(sources):
        name = f"{LABELS_DIR}/{number:04d}-{src.stem}.jsonl"
        entry = {"file": name, "source": str(src.resolve()), "source_sha256": _sha256(src), "config": fingerprint}
        old = previous.get(name)
        if (
            old
            and all(old.get(k) == entry[k] for k in ("source", "source_sha256", "config"))
            and (out / name).is_file()
        ):
            entries[number] = old
        else:
            jobs.append((number, _ShardJob(src, out / name, config, bank), entry))
    by_source = {job.source: (number, entry) for number, job, entry in jobs}
    engine = EXECUTORS.create(executor, where="--executor")
    for source, result in engine.map(_run_job, [job for _, job, _ in jobs], workers):
        number, entry = by_source[source]
        entries[number] = {**entry, **result}
    shards = [entries[n] for n in sorted(entries)]
    manifest = {
        "format_version": FORMAT_VERSION,
        "langtraj_version": __version__,
        "config": asdict(config),
        "windows": sum(s["windows"] for s in shards),
        "shards": shards,
    }
    write_manifest(out, manifest)
    return manifest


def _previous_shards(out: Path) -> dict[str, dict[str, Any]]:
    try:
        manifest = json.loads((out / MANIFEST).read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return {}
    return {s["file"]: s for s in manifest.get("shards", []) if isinstance(s, dict) and "file" in s}


def refresh_manifest_counts(out: Path) -> dict[str, Any]:
    """Recount every shard after labels were changed in place (e.g. by an import)."""
    manifest = read_manifest(out)
    shards = []
    for shard in manifest["shards"]:
        records = read_shard(Path(out) / shard["file"])
        shards.append({**shard, "windows": len(records), **_counts(records)})
    manifest = {**manifest, "shards": shards, "windows": sum(s["windows"] for s in shards)}
    write_manifest(out, manifest)
    return manifest


def with_human_labels(
    record: WindowRecord, human: Sequence[InteractionLabel], config: BuildConfig, bank: PhraseBank = TEMPLATES_ONLY
) -> WindowRecord:
    """The record with its human interaction labels replaced by `human` and its prompt pool redrawn."""
    kept = tuple(i for i in record.labels.interactions if i.source is not LabelSource.HUMAN)
    labels = replace(record.labels, interactions=kept + tuple(human))
    return replace(record, labels=labels, prompts=window_prompts(labels, config, bank))


def load_window(record: WindowRecord) -> Scenario:
    """The scenario window a record labels, read from its source file."""
    scene = read_scenario(record.source, record.record)
    if scene.num_steps == record.num_steps and record.window_start == 0:
        return scene
    return cut_window(
        scene,
        record.window_start,
        WindowSpec(history=record.current_index + 1, future=record.num_steps - record.current_index - 1),
    )
