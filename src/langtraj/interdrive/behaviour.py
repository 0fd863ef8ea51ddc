"""The behaviour kinds a prompt asks of an agent, how each is worded and how the labelers judge it.

Every kind (`Behaviour`) is one entry of `BEHAVIOURS`: the facts that judge it (a single-agent label key of the
taxonomy, a lane change with its side, or an interaction subtype toward another agent, in the fact form of
`adherence`) and a templated `@id` sentence. Counterfactual prompts (`counterfactual`), the prompt reader
(`reader`), the targets derived from the map (`targets`) and instruction following all speak of these kinds.

See docs/interdrive.md ('Counterfactual prompts and instruction following').
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
from typing import Literal

from langtraj.errors import InputError
from langtraj.interdrive.adherence import Fact, lane_change_key
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID, InteractionType
from langtraj.scenario.types import AgentType

Side = Literal["left", "right"]


class Behaviour(StrEnum):
    """The behaviour kinds a counterfactual prompt asks for."""

    TURN_LEFT = "turn_left"
    TURN_RIGHT = "turn_right"
    GO_STRAIGHT = "go_straight"
    LANE_CHANGE_LEFT = "lane_change_left"
    LANE_CHANGE_RIGHT = "lane_change_right"
    STOP = "stop"
    SPEED_UP = "speed_up"
    SLOW_DOWN = "slow_down"
    PULL_OVER = "pull_over"
    GO_FIRST = "go_first"
    YIELD = "yield"
    FOLLOW = "follow"
    CUT_IN = "cut_in"
    OVERTAKE_CUT_IN = "overtake_cut_in"
    BRAKE_HARD = "brake_hard"
    TAILGATE = "tailgate"
    RUN_RED_LIGHT = "run_red_light"
    PULL_OUT = "pull_out"


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
_AT_JUNCTION = ("crossing_intersection",)
"""A turn or going straight is asked for at a junction: the labeler must also see the agent cross one."""

BEHAVIOURS: Mapping[Behaviour, BehaviourSpec] = {
    spec.behaviour: spec
    for spec in (
        BehaviourSpec(
            Behaviour.TURN_LEFT,
            "@{agent} turns left at the next intersection",
            "turn left",
            "turning_left",
            also=_AT_JUNCTION,
        ),
        BehaviourSpec(
            Behaviour.TURN_RIGHT,
            "@{agent} turns right at the next intersection",
            "turn right",
            "turning_right",
            also=_AT_JUNCTION,
        ),
        BehaviourSpec(
            Behaviour.GO_STRAIGHT,
            "@{agent} goes straight through the next intersection",
            "go straight",
            "going_straight",
            also=_AT_JUNCTION,
        ),
        BehaviourSpec(
            Behaviour.LANE_CHANGE_LEFT,
            "@{agent} changes lanes to the left",
            "change lanes to the left",
            "changing_lanes",
            "left",
        ),
        BehaviourSpec(
            Behaviour.LANE_CHANGE_RIGHT,
            "@{agent} changes lanes to the right",
            "change lanes to the right",
            "changing_lanes",
            "right",
        ),
        BehaviourSpec(Behaviour.STOP, "@{agent} comes to a stop and stands still", "stop", "static"),
        BehaviourSpec(Behaviour.SPEED_UP, "@{agent} speeds up", "speed up", "speeding_up"),
        BehaviourSpec(Behaviour.SLOW_DOWN, "@{agent} slows down", "slow down", "slowing_down"),
        BehaviourSpec(
            Behaviour.PULL_OVER, "@{agent} pulls over to the side of the road and stops", "pull over", "pulling_over"
        ),
        BehaviourSpec(
            Behaviour.GO_FIRST,
            "@{agent} takes the right of way over @{other}",
            "go first",
            interaction=InteractionType.PASSING,
            subtype="passing/intersection_with_yielding",
        ),
        BehaviourSpec(
            Behaviour.YIELD,
            "@{agent} yields to @{other}",
            "yield",
            interaction=InteractionType.YIELDING,
            subtype="yielding/intersection",
        ),
        BehaviourSpec(
            Behaviour.FOLLOW,
            "@{agent} follows @{other}",
            "follow",
            interaction=InteractionType.FOLLOWING,
            subtype="following/with_lead",
        ),
        BehaviourSpec(
            Behaviour.CUT_IN,
            "@{agent} cuts in front of @{other}",
            "cut in front of",
            interaction=InteractionType.LANE_CHANGE,
            subtype="lane_change/cut_in",
            exact=True,
            conditioned_as=Behaviour.LANE_CHANGE_LEFT,
        ),
        BehaviourSpec(
            Behaviour.OVERTAKE_CUT_IN,
            "@{agent} overtakes @{other} and cuts in front of it",
            "overtake and cut in front of",
            interaction=InteractionType.OVERTAKING,
            subtype="overtaking/cut_in",
            exact=True,
            conditioned_as=Behaviour.LANE_CHANGE_LEFT,
        ),
        BehaviourSpec(
            Behaviour.BRAKE_HARD,
            "@{agent} brakes hard in front of @{other}",
            "brake hard in front of",
            interaction=InteractionType.PASSING,
            subtype="passing/braking_lead",
            exact=True,
            conditioned_as=Behaviour.STOP,
        ),
        BehaviourSpec(
            Behaviour.TAILGATE,
            "@{agent} tailgates @{other}",
            "tailgate",
            interaction=InteractionType.FOLLOWING,
            subtype="following/tailgating",
            exact=True,
        ),
        BehaviourSpec(
            Behaviour.RUN_RED_LIGHT,
            "@{agent} runs the red light across the path of @{other}",
            "run the red light across the path of",
            interaction=InteractionType.PASSING,
            subtype="passing/red_light_running",
            exact=True,
            conditioned_as=Behaviour.GO_FIRST,
        ),
        BehaviourSpec(
            Behaviour.PULL_OUT,
            "@{agent} pulls out in front of @{other}",
            "pull out in front of",
            interaction=InteractionType.MERGING,
            subtype="merging/pull_out",
            exact=True,
            conditioned_as=Behaviour.GO_FIRST,
        ),
    )
}
"""Every behaviour kind, in the order alternatives are listed."""

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
