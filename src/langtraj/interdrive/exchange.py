"""Import and export of the InterDrive JSON layout: one `{scenario_id}.json` per scene.

Each file holds the scene's interacting pair as `agent_0` and `agent_1`, each with `track_id`,
`interact_with_other_agent` (whether this agent interacts with the other: interactions are asymmetric),
`interaction_type` and `interaction_subtype` (the paper's names, e.g. "Yielding" / "Intersection
yielding"; keys such as "yielding" / "intersection" are read too) and `no_behavior_description` (the
free text of Other / Undefined behavior, else empty). Export writes the best-sourced pair of each window
(human, then SUMO ground truth, then the detector); import turns files into human labels of the
matching windows and redraws their prompt pools.

See docs/interdrive.md.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from langtraj.errors import InputError
from langtraj.fileio import atomic_open
from langtraj.interdrive.dataset import (
    BuildConfig,
    WindowRecord,
    iter_records,
    phrase_bank,
    read_manifest,
    refresh_manifest_counts,
    with_human_labels,
    write_shard,
)
from langtraj.interdrive.labels import InteractionLabel, LabelSource
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID, InteractionType, Subtype, parse_subtype

SOURCE_RANK = (LabelSource.HUMAN, LabelSource.GROUND_TRUTH, LabelSource.DETECTOR)
"""Which labels an export prefers, best first."""

NO_INTERACTION = SUBTYPES_BY_ID["other/no_interaction"]
UNDEFINED = SUBTYPES_BY_ID["other/undefined"]
AGENT_KEYS = ("agent_0", "agent_1")


@dataclass(frozen=True)
class ExportSummary:
    written: int
    skipped: int  # windows with no labelled pair


def _rank(label: InteractionLabel) -> int:
    return SOURCE_RANK.index(label.source)


def _pair(record: WindowRecord) -> tuple[int, int] | None:
    """The window's interacting pair: from its best-sourced interaction between two agents."""
    pairs = [i for i in record.labels.interactions if i.other_id >= 0 and i.subtype.type is not InteractionType.OTHER]
    if not pairs:
        return None
    best = min(pairs, key=lambda i: (_rank(i), i.start, i.track_id, i.other_id))
    return best.track_id, best.other_id


def agent_entry(track_id: int, subtype: Subtype, text: str = "") -> dict[str, Any]:
    """One agent's entry of an InterDrive JSON document: what `track_id` does towards the other agent."""
    return {
        "track_id": track_id,
        "interact_with_other_agent": subtype.type is not InteractionType.OTHER,
        "interaction_type": subtype.type.title,
        "interaction_subtype": subtype.name,
        "no_behavior_description": text,
    }


def _agent_entry(record: WindowRecord, agent: int, other: int) -> dict[str, Any]:
    towards = [i for i in record.labels.interactions if i.track_id == agent and i.other_id == other]
    if not towards:
        return agent_entry(agent, NO_INTERACTION)
    best = min(towards, key=lambda i: (_rank(i), i.start))
    return agent_entry(agent, best.subtype, best.text)


def write_scene(out: Path, scenario_id: str, first: dict[str, Any], second: dict[str, Any]) -> Path:
    """Write one window's InterDrive JSON document `{scenario_id}.json` into `out`, atomically."""
    path = Path(out) / f"{scenario_id}.json"
    with atomic_open(path, "w") as fh:
        json.dump({"scenario_id": scenario_id, AGENT_KEYS[0]: first, AGENT_KEYS[1]: second}, fh, indent=1)
    return path


def export_json(dataset: Path, out: Path) -> ExportSummary:
    """Write `{scenario_id}.json` for every window of `dataset` that has an interacting pair."""
    written = skipped = 0
    for _, records in iter_records(dataset):
        for record in records:
            pair = _pair(record)
            if pair is None:
                skipped += 1
                continue
            a, b = pair
            write_scene(out, record.scenario_id, _agent_entry(record, a, b), _agent_entry(record, b, a))
            written += 1
    return ExportSummary(written, skipped)


# ---------------------------------------------------------------- import


def _get(obj: Mapping[str, Any], name: str, kind: type | tuple[type, ...], where: str) -> Any:
    if name not in obj:
        raise InputError(f"missing field {name!r}", where=where)
    value = obj[name]
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise InputError(f"field {name!r} has the wrong type: {value!r}", where=where)
    return value


def _subtype(entry: Mapping[str, Any], where: str) -> Subtype:
    kind = _get(entry, "interaction_type", str, where)
    return parse_subtype(kind, _get(entry, "interaction_subtype", str, where), f"{where}.interaction_subtype")


def parse_scene(doc: Any, record: WindowRecord, path: Path) -> list[InteractionLabel]:
    """Human interaction labels from one InterDrive JSON document, checked against the window's tracks."""
    if not isinstance(doc, Mapping):
        raise InputError("expected a JSON object", path=path)
    entries = []
    for key in AGENT_KEYS:
        entry = doc.get(key)
        if not isinstance(entry, Mapping):
            raise InputError(f"missing or malformed {key!r}", path=path)
        track = _get(entry, "track_id", int, key)
        if track not in record.track_ids:
            raise InputError(f"track {track} is not in window {record.scenario_id}", path=path, where=f"{key}.track_id")
        entries.append((key, entry, track))
    labels = []
    for (key, entry, track), (_, _, other) in zip(entries, entries[::-1], strict=True):
        try:
            interacts = _get(entry, "interact_with_other_agent", bool, key)
            sub = _subtype(entry, key)
            text = _get(entry, "no_behavior_description", str, key) if "no_behavior_description" in entry else ""
        except InputError as exc:
            raise exc.located(path=path) from None
        if not interacts and sub.type is not InteractionType.OTHER:
            raise InputError(f"{sub.name!r} given but interact_with_other_agent is false", path=path, where=key)
        if sub is UNDEFINED and not text.strip():
            raise InputError("Undefined behavior needs a no_behavior_description", path=path, where=key)
        labels.append(
            InteractionLabel(track, other, sub, LabelSource.HUMAN, record.current_index, record.num_steps, text.strip())
        )
    return labels


def import_json(json_dir: Path, dataset: Path) -> int:
    """Merge every `*.json` in `json_dir` into `dataset` as human labels; returns the windows updated.

    Everything is checked before anything is written: an unknown scenario id, track or label names the
    file and field, and the dataset stays as it was."""
    files = sorted(Path(json_dir).glob("*.json"))
    if not Path(json_dir).is_dir():
        raise InputError("no such folder", path=json_dir)
    if not files:
        raise InputError("no *.json files", path=json_dir)
    manifest = read_manifest(dataset)
    built = manifest["config"]
    config = BuildConfig(
        seed=built["seed"],
        prompts_per_agent=built["prompts_per_agent"],
        llm_url=built.get("llm_url"),
        llm_model=built.get("llm_model", "gpt-4o-mini"),
    )
    bank = phrase_bank(config)
    shards = list(iter_records(dataset))
    where = {rec.scenario_id: (n, i) for n, (_, recs) in enumerate(shards) for i, rec in enumerate(recs)}
    updates: dict[tuple[int, int], list[InteractionLabel]] = {}
    for path in files:
        try:
            doc = json.loads(path.read_text())
        except json.JSONDecodeError as exc:
            raise InputError(f"not JSON: {exc.msg} at line {exc.lineno}", path=path) from None
        scenario_id = str(doc.get("scenario_id", path.stem)) if isinstance(doc, Mapping) else path.stem
        if scenario_id not in where:
            raise InputError(f"no window {scenario_id!r} in {dataset}", path=path, where="scenario_id")
        n, i = where[scenario_id]
        updates[(n, i)] = parse_scene(doc, shards[n][1][i], path)
    for n, (shard_path, records) in enumerate(shards):
        touched = [i for (m, i) in updates if m == n]
        if not touched:
            continue
        new = list(records)
        for i in touched:
            new[i] = with_human_labels(records[i], updates[(n, i)], config, bank)
        write_shard(shard_path, new)
    refresh_manifest_counts(dataset)
    return len(updates)


def records_by_id(dataset: Path) -> dict[str, WindowRecord]:
    """Every window record of a dataset by scenario id."""
    return {rec.scenario_id: rec for _, recs in iter_records(dataset) for rec in recs}
