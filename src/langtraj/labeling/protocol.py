"""What an annotator submits for one window, checked against the taxonomy and the window's agents.

The paper's protocol ('Human-Labeling Process'): the interacting pair (step 1), each agent's interaction
type towards the other (step 2, asymmetric) and its subtype (step 3), with Other as the escape (undefined
behaviour with free text, no interaction, unknown status). Agreement compares type and subtype per agent
exactly (`PairLabels.key`). See docs/labeling.md ('Protocol').
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from langtraj.errors import InputError
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID, Subtype

MAX_TEXT = 2000
UNDEFINED = SUBTYPES_BY_ID["other/undefined"]


@dataclass(frozen=True)
class AgentChoice:
    """Agent `track_id` towards `other_id` is `subtype`; `text` describes Other / Undefined behavior."""

    track_id: int
    other_id: int
    subtype: Subtype
    text: str = ""

    def to_json(self) -> dict[str, Any]:
        return {"track_id": self.track_id, "other_id": self.other_id, "subtype": self.subtype.id, "text": self.text}


@dataclass(frozen=True)
class PairLabels:
    """A window's labels: the pair and one choice per agent of it, towards the other."""

    pair: tuple[int, int]
    choices: tuple[AgentChoice, AgentChoice]

    def key(self) -> frozenset[tuple[int, int, str]]:
        """What agreement compares: each agent's type and subtype towards the other (not the free text)."""
        return frozenset((c.track_id, c.other_id, c.subtype.id) for c in self.choices)

    def check_window(self, agents: Collection[int]) -> None:
        """Raise InputError unless both agents of the pair are among the window's `agents`."""
        for track in self.pair:
            if track not in agents:
                raise InputError(f"agent {track} is not in this window", where="pair")

    def to_json(self) -> dict[str, Any]:
        return {"pair": list(self.pair), "choices": [c.to_json() for c in self.choices]}


def parse_subtype_id(text: str, where: str) -> Subtype:
    try:
        return SUBTYPES_BY_ID[text]
    except KeyError:
        raise InputError(f"{text!r} is not a subtype of the InterDrive taxonomy", where=where) from None


def parse_choice(obj: Mapping[str, Any], where: str) -> AgentChoice:
    subtype = parse_subtype_id(str(obj.get("subtype", "")), f"{where}.subtype")
    text = obj.get("text") or ""
    if not isinstance(text, str):
        raise InputError("must be a string", where=f"{where}.text")
    text = text.strip()
    if len(text) > MAX_TEXT:
        raise InputError(f"longer than {MAX_TEXT} characters", where=f"{where}.text")
    if subtype is UNDEFINED and not text:
        raise InputError("Other / Undefined behavior needs a description", where=f"{where}.text")
    if subtype is not UNDEFINED and text:
        raise InputError("free text belongs only to Other / Undefined behavior", where=f"{where}.text")
    track, other = obj.get("track_id"), obj.get("other_id")
    for name, value in (("track_id", track), ("other_id", other)):
        if isinstance(value, bool) or not isinstance(value, int):
            raise InputError(f"must be an integer, got {value!r}", where=f"{where}.{name}")
    return AgentChoice(int(track), int(other), subtype, text)  # type: ignore[arg-type]


def parse_labels(pair: Sequence[Any], choices: Sequence[Mapping[str, Any]]) -> PairLabels:
    """Labels from a submission; anything outside the taxonomy or the protocol raises InputError naming it.
    Whether the agents are in the window is checked where the window is at hand (`PairLabels.check_window`)."""
    if len(pair) != 2 or any(isinstance(t, bool) or not isinstance(t, int) for t in pair):
        raise InputError("must be two track ids", where="pair")
    a, b = int(pair[0]), int(pair[1])
    if a == b:
        raise InputError("an agent cannot interact with itself", where="pair")
    if len(choices) != 2:
        raise InputError("must hold one choice per agent of the pair", where="choices")
    parsed = [parse_choice(c, f"choices[{i}]") for i, c in enumerate(choices)]
    by_agent = {(c.track_id, c.other_id): c for c in parsed}
    if set(by_agent) != {(a, b), (b, a)}:
        raise InputError(f"must hold {a} towards {b} and {b} towards {a}", where="choices")
    return PairLabels((a, b), (by_agent[(a, b)], by_agent[(b, a)]))


def suggestion_for(suggestions: Sequence[Mapping[str, Any]], track_id: int, other_id: int) -> str | None:
    """The detector's subtype for `track_id` towards `other_id`, if it found one."""
    for s in suggestions:
        if s["track_id"] == track_id and s["other_id"] == other_id:
            return str(s["subtype"])
    return None
