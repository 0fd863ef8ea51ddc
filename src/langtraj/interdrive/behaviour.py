"""The behaviour kinds a prompt asks of an agent, how each is worded and how the labelers judge it.

Every kind (`Behaviour`) is one entry of `BEHAVIOURS`: the facts that judge it (a single-agent label key of the
taxonomy, a lane change with its side, or an interaction subtype toward another agent, in the fact form of
`adherence`) and a templated `@id` sentence. Counterfactual prompts (`counterfactual`), the prompt reader
(`reader`), the targets derived from the map (`targets`) and instruction following all speak of these kinds.

See docs/interdrive.md ('Counterfactual prompts and instruction following').
"""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

from langtraj.errors import InputError
from langtraj.interdrive.adherence import Fact, lane_change_key
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID, InteractionType
from langtraj.registry import Registry
from langtraj.scenario.types import AgentType

Side = Literal["left", "right"]


def _load_builtin() -> None:
    """Import the shipped behaviours, which register themselves (by name: the modules build on this one)."""
    importlib.import_module("langtraj.interdrive.behaviours.builtin")


KINDS: Registry[Any] = Registry("behaviour", loader=_load_builtin)
"""Every behaviour (`interdrive.behaviours.BehaviourKind` classes, registered with `behaviours.register`); in the
order alternatives are listed: `names()`."""

SHIPPED: tuple[str, ...] = (
    "turn_left", "turn_right", "go_straight", "lane_change_left", "lane_change_right", "stop", "speed_up", "slow_down",
    "pull_over", "go_first", "yield", "follow", "cut_in", "overtake_cut_in", "brake_hard", "tailgate",
    "run_red_light", "pull_out",
)  # fmt: skip
"""The shipped behaviours, in the order alternatives are listed."""


def names() -> tuple[str, ...]:
    """Every registered behaviour in the order alternatives are listed: the shipped ones in `SHIPPED`'s order, then
    any other in the order it registered (whichever module was imported first)."""
    registered = KINDS.names()
    return (*(n for n in SHIPPED if n in registered), *(n for n in registered if n not in SHIPPED))


class _Names(type):
    """Iterating `Behaviour` gives the registered behaviours in order; calling it gives the one instance of a name."""

    _interned: dict[str, Behaviour]

    def __iter__(cls) -> Iterator[Behaviour]:
        return iter([cls(name) for name in names()])

    def __call__(cls, value: object) -> Behaviour:
        name = str(value)
        found = cls._interned.get(name)
        if found is None:
            found = cls._interned[name] = super().__call__(name)
        return found


class Behaviour(str, metaclass=_Names):
    """The name of a behaviour a prompt asks for: a string, one instance per name (so `is` compares), with the shipped
    behaviours as constants. Every behaviour is a module of `interdrive.behaviours` registered in its `KINDS`;
    iterating this class lists them (docs/design.md, 'Behaviours')."""

    __slots__ = ()
    _interned: ClassVar[dict[str, Behaviour]] = {}

    @property
    def value(self) -> str:
        return str.__str__(self)

    def __repr__(self) -> str:
        return f"Behaviour({str.__str__(self)!r})"

    def __str__(self) -> str:
        return str.__str__(self)

    def __reduce__(self) -> tuple[Any, ...]:
        return (Behaviour, (str.__str__(self),))

    TURN_LEFT: ClassVar[Behaviour]
    TURN_RIGHT: ClassVar[Behaviour]
    GO_STRAIGHT: ClassVar[Behaviour]
    LANE_CHANGE_LEFT: ClassVar[Behaviour]
    LANE_CHANGE_RIGHT: ClassVar[Behaviour]
    STOP: ClassVar[Behaviour]
    SPEED_UP: ClassVar[Behaviour]
    SLOW_DOWN: ClassVar[Behaviour]
    PULL_OVER: ClassVar[Behaviour]
    GO_FIRST: ClassVar[Behaviour]
    YIELD: ClassVar[Behaviour]
    FOLLOW: ClassVar[Behaviour]
    CUT_IN: ClassVar[Behaviour]
    OVERTAKE_CUT_IN: ClassVar[Behaviour]
    BRAKE_HARD: ClassVar[Behaviour]
    TAILGATE: ClassVar[Behaviour]
    RUN_RED_LIGHT: ClassVar[Behaviour]
    PULL_OUT: ClassVar[Behaviour]


for _name in SHIPPED:
    setattr(Behaviour, _name.upper(), Behaviour(_name))


@dataclass(frozen=True)
class BehaviourSpec:
    """How one behaviour is asked for and judged: `template` is the `@id` sentence (`{agent}`, and `{other}`
    for pair behaviours); `label` the taxonomy label key judging it (with `side` for a lane change, judged by
    `adherence.lane_change_key`), and `also` further label keys that must hold with it; `interaction` the
    interaction type toward the other agent judging a pair behaviour; `manoeuvre` the words of a warning
    ("@12 cannot turn left")."""

    behaviour: Behaviour
    template: str
    manoeuvre: str
    label: str | None = None
    side: Side | None = None
    interaction: InteractionType | None = None
    also: tuple[str, ...] = ()
    subtype: str | None = None
    """The interaction subtype judging a pair behaviour unless another is given (`behaviour_facts`)."""
    exact: bool = False
    """Whether a typed prompt's pair behaviour is judged by `subtype` itself, not by any subtype of its type (a cut-in
    is one kind of lane change toward another agent; `PromptReading.followed`)."""
    conditioned_as: Behaviour | None = None
    """The kind whose sentence the model, which never saw this kind in training, is conditioned on instead of the
    typed words (running a red light across another agent's path, or pulling out in front of it: going first; braking
    hard in front of another agent: a stop; a cut-in, with or without an overtake first: a lane change, to the side
    its target takes; `sim.prompts.conditioning_sentence`)."""
    first: bool = False
    """Whether a pair behaviour's agent passes the conflict point first (going first, running a red light across the
    other's way, pulling out in front of it: `BehaviourTarget.first`)."""

    @property
    def is_pair(self) -> bool:
        return self.interaction is not None

    @property
    def is_turn(self) -> bool:
        return self.label in _TURN_LABELS

    @property
    def is_lane_change(self) -> bool:
        return self.label == "changing_lanes"

    @property
    def label_keys(self) -> tuple[str, ...]:
        """The taxonomy label keys a prompt for this behaviour states (none for a pair behaviour)."""
        return () if self.label is None else (self.label, *self.also)

    @property
    def fact_key(self) -> str | None:
        """The label fact key judging a single-agent behaviour."""
        if self.label is None:
            return None
        return lane_change_key(self.side) if self.is_lane_change and self.side else self.label

    def text(self, agent: int, other: int | None = None) -> str:
        """The behaviour's `@id` sentence for `agent` (and `other`)."""
        if self.is_pair and other is None:
            raise InputError(f"behaviour {self.behaviour.value!r} needs another agent")
        return self.template.format(agent=agent, other=other)


_TURN_LABELS = ("turning_left", "turning_right", "going_straight")
AT_JUNCTION = ("crossing_intersection",)
"""A turn or going straight is asked for at a junction: the labeler must also see the agent cross one."""


class _Specs(Mapping[Behaviour, BehaviourSpec]):
    """Every registered behaviour's spec (`BehaviourKind.spec`), in the order alternatives are listed."""

    def __getitem__(self, behaviour: object) -> BehaviourSpec:
        if str(behaviour) not in KINDS.names():  # membership: order does not matter
            raise KeyError(behaviour)
        return KINDS.get(str(behaviour)).spec

    def __iter__(self) -> Iterator[Behaviour]:
        return iter(Behaviour)

    def __len__(self) -> int:
        return len(KINDS.names())


BEHAVIOURS: Mapping[Behaviour, BehaviourSpec] = _Specs()
"""Every behaviour's spec, in the order alternatives are listed (each declared in its module of
`interdrive.behaviours`)."""

PAIR_SUBTYPES: tuple[tuple[str, str], ...] = (
    ("yielding/intersection", "passing/intersection_with_yielding"),
    ("yielding/to_merging_or_lane_change", "passing/intersection_with_yielding"),
    ("yielding/roundabout", "passing/roundabout"),
    ("yielding/to_pedestrian", "passing/pedestrian"),
    ("yielding/pedestrian_to_vehicle", "passing/vru_crossing"),
)
"""(yield subtype, go-first subtype) of an agent toward the same other agent, as the detector writes each side of a
yield: a car yielding at a junction or going through it first, a car waiting for a pedestrian or passing it, a
pedestrian waiting for a car or crossing in front of it. The first row of a go-first subtype is its yield."""

_YIELD_OF = {go: stay for stay, go in reversed(PAIR_SUBTYPES)}
_GO_FIRST_OF = dict(PAIR_SUBTYPES)


def opposite_subtype(subtype: str, agent_type: AgentType) -> str | None:
    """The go-first subtype of an agent whose yield is `subtype`, or its yield subtype when `subtype` is a go-first
    one (`PAIR_SUBTYPES`); None for other subtypes. A cyclist crossing in front of a car (`passing/vru_crossing`)
    would yield as a vehicle does at a junction."""
    if subtype in _GO_FIRST_OF:
        return _GO_FIRST_OF[subtype]
    if subtype == "passing/vru_crossing" and agent_type != AgentType.PEDESTRIAN:
        return "yielding/intersection"
    return _YIELD_OF.get(subtype)


def behaviour_facts(
    behaviour: Behaviour, track_id: int, other_id: int | None = None, subtype: str | None = None
) -> frozenset[Fact]:
    """The facts that judge `behaviour` of `track_id`: its label facts, or for a pair behaviour the interaction
    `subtype` (by default the spec's: the junction one for going first or yielding) toward `other_id`."""
    spec = BEHAVIOURS[behaviour]
    if not spec.is_pair:
        return frozenset({("label", track_id, key) for key in (str(spec.fact_key), *spec.also)})
    if other_id is None:
        raise InputError(f"behaviour {behaviour.value!r} needs another agent")
    subtype = subtype or spec.subtype
    if subtype is None or subtype not in SUBTYPES_BY_ID:
        raise InputError(f"unknown interaction subtype {subtype!r} for behaviour {behaviour.value!r}")
    if SUBTYPES_BY_ID[subtype].type is not spec.interaction:
        raise InputError(f"subtype {subtype!r} does not judge behaviour {behaviour.value!r}")
    return frozenset({("interaction", track_id, other_id, subtype)})
