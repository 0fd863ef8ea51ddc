"""Label records of one window: single-agent labels, undecided labels and interaction labels.

Plain frozen dataclasses with a JSON form (`to_json` / `from_json`); the JSON readers validate every
key against the taxonomy and name the field that is wrong. Steps are window steps, [start, end).

See docs/interdrive.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from langtraj.errors import InputError
from langtraj.interdrive.taxonomy import InteractionType, Subtype, check_params, parse_subtype

SCHEMA_VERSION = 1


class LabelSource(StrEnum):
    """Where an interaction label comes from."""

    GROUND_TRUTH = "ground_truth"  # mapped from SUMO's events (synthesized scenes); stands in for human labels
    DETECTOR = "detector"  # the rule-based detector on trajectories and map
    HUMAN = "human"  # the labeling tool or an imported InterDrive JSON file


@dataclass(frozen=True)
class AgentLabel:
    """Single-agent label `key` (see `taxonomy.SINGLE_AGENT_LABELS`) of track `track_id` over [start, end)."""

    track_id: int
    key: str
    start: int
    end: int
    params: Mapping[str, str] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"track_id": self.track_id, "label": self.key, "start": self.start, "end": self.end}
        if self.params:
            out["params"] = dict(self.params)
        return out

    @classmethod
    def from_json(cls, obj: Mapping[str, Any], where: str) -> AgentLabel:
        key = _field(obj, "label", str, where)
        params = {str(k): str(v) for k, v in dict(obj.get("params") or {}).items()}
        check_params(key, params, where)
        return cls(
            _field(obj, "track_id", int, where),
            key,
            _field(obj, "start", int, where),
            _field(obj, "end", int, where),
            params,
        )


@dataclass(frozen=True)
class Undecided:
    """A label the heuristics could not decide for `track_id`, and why (e.g. the map has no lane
    connectivity)."""

    track_id: int
    key: str
    reason: str

    def to_json(self) -> dict[str, Any]:
        return {"track_id": self.track_id, "label": self.key, "reason": self.reason}

    @classmethod
    def from_json(cls, obj: Mapping[str, Any], where: str) -> Undecided:
        return cls(
            _field(obj, "track_id", int, where), _field(obj, "label", str, where), _field(obj, "reason", str, where)
        )


@dataclass(frozen=True)
class InteractionLabel:
    """Agent `track_id` interacts with `other_id` (ordered, asymmetric) as `subtype` over [start, end).

    `other_id` is -1 for Other/no interaction and for interactions without a second agent; `text` is
    the free description of Other/undefined behaviour.
    """

    track_id: int
    other_id: int
    subtype: Subtype
    source: LabelSource
    start: int
    end: int
    text: str = ""

    @property
    def type(self) -> InteractionType:
        return self.subtype.type

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "track_id": self.track_id,
            "other_id": self.other_id,
            "type": self.subtype.type.value,
            "subtype": self.subtype.key,
            "source": self.source.value,
            "start": self.start,
            "end": self.end,
        }
        if self.text:
            out["text"] = self.text
        return out

    @classmethod
    def from_json(cls, obj: Mapping[str, Any], where: str) -> InteractionLabel:
        sub = parse_subtype(_field(obj, "type", str, where), _field(obj, "subtype", str, where), where)
        try:
            source = LabelSource(_field(obj, "source", str, where))
        except ValueError:
            known = ", ".join(s.value for s in LabelSource)
            raise InputError(f"unknown label source {obj['source']!r}; known: {known}", where=where) from None
        return cls(
            _field(obj, "track_id", int, where),
            _field(obj, "other_id", int, where),
            sub,
            source,
            _field(obj, "start", int, where),
            _field(obj, "end", int, where),
            str(obj.get("text", "")),
        )


@dataclass(frozen=True)
class WindowLabels:
    """Every label of one scenario window."""

    scenario_id: str
    agent_labels: tuple[AgentLabel, ...] = ()
    undecided: tuple[Undecided, ...] = ()
    interactions: tuple[InteractionLabel, ...] = ()

    def labels_of(self, track_id: int) -> tuple[AgentLabel, ...]:
        return tuple(lab for lab in self.agent_labels if lab.track_id == track_id)

    def interactions_of(self, track_id: int) -> tuple[InteractionLabel, ...]:
        return tuple(i for i in self.interactions if i.track_id == track_id)

    def to_json(self) -> dict[str, Any]:
        return {
            "scenario_id": self.scenario_id,
            "agent_labels": [lab.to_json() for lab in self.agent_labels],
            "undecided": [u.to_json() for u in self.undecided],
            "interactions": [i.to_json() for i in self.interactions],
        }

    @classmethod
    def from_json(cls, obj: Mapping[str, Any], where: str = "labels") -> WindowLabels:
        if not isinstance(obj, Mapping):
            raise InputError(f"expected an object, got {type(obj).__name__}", where=where)
        sid = _field(obj, "scenario_id", str, where)
        here = f"{where} {sid}"
        return cls(
            sid,
            tuple(
                AgentLabel.from_json(o, f"{here} agent_labels[{i}]")
                for i, o in enumerate(_list(obj, "agent_labels", here))
            ),
            tuple(
                Undecided.from_json(o, f"{here} undecided[{i}]") for i, o in enumerate(_list(obj, "undecided", here))
            ),
            tuple(
                InteractionLabel.from_json(o, f"{here} interactions[{i}]")
                for i, o in enumerate(_list(obj, "interactions", here))
            ),
        )


def _field(obj: Mapping[str, Any], name: str, kind: type, where: str) -> Any:
    if not isinstance(obj, Mapping) or name not in obj:
        raise InputError(f"missing field {name!r}", where=where)
    value = obj[name]
    if kind is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise InputError(f"field {name!r} must be an integer, got {value!r}", where=where)
    if kind is str and not isinstance(value, str):
        raise InputError(f"field {name!r} must be a string, got {value!r}", where=where)
    return value


def _list(obj: Mapping[str, Any], name: str, where: str) -> list[Any]:
    value = obj.get(name, [])
    if not isinstance(value, list):
        raise InputError(f"field {name!r} must be a list", where=where)
    return value
