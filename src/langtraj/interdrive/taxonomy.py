"""The InterDrive vocabulary: single-agent labels and the interaction taxonomy (one source of truth).

Labels, prompts, the labeling tool and the model all take their keys, names and definitions from here.
Interaction types and subtypes are those of the paper's appendix 'InterDrive Interaction Type
Definitions', plus Other; single-agent labels are those of its section 'Heuristic Annotation Process'.
Keys are stable snake_case strings (they are stored in label files); names are the paper's wording.

See docs/interdrive.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
from types import MappingProxyType

from langtraj.errors import InputError
from langtraj.scenario.types import AgentType


class InteractionType(StrEnum):
    """The six interaction types of InterDrive, plus Other."""

    LANE_CHANGE = "lane_change"
    FOLLOWING = "following"
    YIELDING = "yielding"
    PASSING = "passing"
    OVERTAKING = "overtaking"
    MERGING = "merging"
    OTHER = "other"

    @property
    def title(self) -> str:
        return _TYPE_TITLES[self]


_TYPE_TITLES = {
    InteractionType.LANE_CHANGE: "Lane Change",
    InteractionType.FOLLOWING: "Following/Stopping Behind",
    InteractionType.YIELDING: "Yielding",
    InteractionType.PASSING: "Passing",
    InteractionType.OVERTAKING: "Overtaking",
    InteractionType.MERGING: "Merging",
    InteractionType.OTHER: "Other",
}


@dataclass(frozen=True)
class Subtype:
    """One interaction subtype: `type/key` is its id, `name` and `definition` are the paper's."""

    type: InteractionType
    key: str
    name: str
    definition: str

    @property
    def id(self) -> str:
        return f"{self.type.value}/{self.key}"

    @property
    def added(self) -> bool:
        """Whether this is one of LangTraj's additions to the paper's subtypes (`ADDED_SUBTYPES`)."""
        return self.id in ADDED_SUBTYPES


def _subtypes(kind: InteractionType, *rows: tuple[str, str, str]) -> tuple[Subtype, ...]:
    return tuple(Subtype(kind, key, name, definition) for key, name, definition in rows)


SUBTYPES: tuple[Subtype, ...] = (
    *_subtypes(
        InteractionType.LANE_CHANGE,
        (
            "for_turn_or_exit",
            "Changing lane for turn or exit",
            "Moving to another lane in preparation for turning or exiting.",
        ),
        ("for_overtaking", "Changing lane for overtaking", "Moving to another lane to pass a slower vehicle."),
        (
            "avoiding_slower_traffic",
            "Lane-change for avoiding obstacles or slower traffic",
            "Changing lanes to bypass road obstacles or slower-moving vehicles.",
        ),
        ("for_merging", "Lane-change for merging", "Changing lanes to merge into another stream of traffic."),
        (
            "with_lead_or_trail",
            "Changing lane with lead or trail",
            "Performing a lane change with another vehicle directly ahead (lead) or behind (trail), requiring extra "
            "caution.",
        ),
        (
            "cut_in",
            "Cutting in",
            "Changing into another vehicle's lane just ahead of it, so that it must make room (Euro NCAP's cut-in; "
            "LangTraj's addition to the paper's subtypes, for safety-critical tests).",
        ),
    ),
    *_subtypes(
        InteractionType.FOLLOWING,
        (
            "with_lead",
            "Following with a lead vehicle",
            "Adjusting speed to maintain a safe distance while following another vehicle.",
        ),
        ("slow_lead", "Following a slow-moving lead", "Driving slower than desired to follow a slower vehicle ahead."),
        (
            "tailgating",
            "Tailgating",
            "Driving too closely behind another vehicle, often considered aggressive driving.",
        ),
        (
            "stopping_behind_lead",
            "Stopping behind a lead vehicle",
            "Coming to a stop behind another vehicle, typically at traffic lights or stop signs.",
        ),
        (
            "stopping_behind_intersection",
            "Stopping behind an intersection",
            "Coming to a stop before entering an intersection.",
        ),
    ),
    *_subtypes(
        InteractionType.YIELDING,
        ("intersection", "Intersection yielding", "Yielding to oncoming traffic or other road users at intersections."),
        (
            "before_merge_or_lane_change",
            "Yielding before merging or lane-change",
            "Yielding to ongoing traffic when changing a lane or merging.",
        ),
        (
            "to_merging_or_lane_change",
            "Yielding to merging or lane-change cars",
            "Yielding to cars that change lanes or merge into the current lane.",
        ),
        (
            "to_pedestrian",
            "Waiting for a pedestrian to cross",
            "Yielding to a pedestrian at a crosswalk or intersection, allowing them to cross safely.",
        ),
        ("roundabout", "Roundabout yielding", "Yielding to vehicles already in a roundabout before entering."),
        (
            "pedestrian_to_vehicle",
            "Pedestrian yielding to vehicles",
            "Pedestrians pause and give way to oncoming vehicles before crossing the road.",
        ),
    ),
    *_subtypes(
        InteractionType.PASSING,
        (
            "intersection_with_yielding",
            "Passing through an intersection with yielding vehicles",
            "Moving through an intersection without yielding, while other cars yield.",
        ),
        (
            "pedestrian",
            "Passing a pedestrian",
            "Moving past a pedestrian walking near the road or on a crosswalk, ensuring a safe distance.",
        ),
        (
            "pedestrian_passing_vehicle",
            "Pedestrian passing a vehicle",
            "A pedestrian moves around or crosses in front of a stationary vehicle.",
        ),
        (
            "roundabout",
            "Passing through a roundabout",
            "Navigating through a roundabout without stopping, maintaining the right of way.",
        ),
        (
            "maintaining_speed",
            "Maintaining speed while driving",
            "Driving straight or turning while maintaining the original speed without yielding or merging.",
        ),
        ("as_leading_vehicle", "Passing as a leading vehicle", "Passing with other vehicles following."),
        (
            "braking_lead",
            "Braking hard as a leading vehicle",
            "Braking hard in its lane with a vehicle following close behind, which must brake in turn (Euro NCAP's "
            "braking lead vehicle; LangTraj's addition to the paper's subtypes, for safety-critical tests).",
        ),
        (
            "red_light_running",
            "Running a red light",
            "Crossing the stop line of its lane while the signal shows stop, across the path of another road user who "
            "has to give way or brake (NHTSA's running-a-red-light pre-crash scenario; LangTraj's addition to the "
            "paper's subtypes, for safety-critical tests).",
        ),
        (
            "vru_crossing",
            "Pedestrian or cyclist crossing the road",
            "Pedestrians or cyclists crossing the road, usually with vehicles yielding.",
        ),
    ),
    *_subtypes(
        InteractionType.OVERTAKING,
        (
            "car_avoidance",
            "Car avoidance",
            "Taking evasive action to avoid another vehicle, often involving swerving, braking, or accelerating.",
        ),
        (
            "standard",
            "Standard overtaking",
            "Passing a slower vehicle by moving to an adjacent lane and returning to the original lane.",
        ),
        (
            "high_speed",
            "High-speed overtaking",
            "Passing at higher speeds on highways, requiring careful attention to speed and distance.",
        ),
        (
            "cut_in",
            "Overtaking and cutting in",
            "Passing another vehicle from behind and changing into its lane just ahead of it, so that it must make "
            "room (NHTSA's pre-crash lane-change scenarios; LangTraj's addition to the paper's subtypes, for "
            "safety-critical tests).",
        ),
    ),
    *_subtypes(
        InteractionType.MERGING,
        ("standard", "Standard merge", "Entering the flow of traffic from a merging lane or on-ramp."),
        (
            "lane_reduction",
            "Lane reduction merge",
            "Merging into an adjacent lane when a lane ends due to road conditions.",
        ),
        ("zipper", "Zipper merge", "A coordinated merge where vehicles in two lanes alternate into a single lane."),
        (
            "on_ramp_accelerating",
            "Highway on-ramp accelerating merge",
            "Entering a highway while accelerating to match traffic speed.",
        ),
        ("late", "Late merge", "Merging closer to the end of the merging lane in congested traffic."),
        (
            "pull_out",
            "Pulling out in front of",
            "Entering another vehicle's path from a side road, a driveway or the kerb, from (nearly) standing, just "
            "ahead of it, so that it must brake or give way (NHTSA's pre-crash scenarios of a vehicle turning or "
            "crossing at a non-signalized junction; LangTraj's addition to the paper's subtypes, for safety-critical "
            "tests).",
        ),
    ),
    *_subtypes(
        InteractionType.OTHER,
        (
            "undefined",
            "Undefined behavior",
            "A behaviour none of the predefined options describes; the labeler types a description.",
        ),
        ("no_interaction", "No interaction", "No interaction occurs."),
        ("unknown", "Unknown status", "The behaviour cannot be determined from insufficient or unclear data."),
    ),
)

ADDED_SUBTYPES = frozenset(
    {
        "lane_change/cut_in",
        "overtaking/cut_in",
        "passing/braking_lead",
        "passing/red_light_running",
        "merging/pull_out",
    }
)
"""LangTraj's additions to the paper's subtypes, what a safety-critical test asks by name; SUMO's events give none of
them (`ground_truth`), so scoring the detector against SUMO leaves them out."""

SUBTYPES_BY_ID: Mapping[str, Subtype] = MappingProxyType({s.id: s for s in SUBTYPES})


def subtypes_of(kind: InteractionType) -> tuple[Subtype, ...]:
    return tuple(s for s in SUBTYPES if s.type is kind)


def _norm(text: str) -> str:
    return " ".join(text.replace("_", " ").replace("-", " ").lower().split())


def parse_type(text: str, where: str | None = None) -> InteractionType:
    """An interaction type from its key ("yielding") or paper title ("Yielding"), case-insensitively."""
    wanted = _norm(text)
    for kind in InteractionType:
        if wanted in (_norm(kind.value), _norm(kind.title)):
            return kind
    known = ", ".join(k.value for k in InteractionType)
    raise InputError(f"unknown interaction type {text!r}; known: {known}", where=where)


def parse_subtype(kind: InteractionType | str, text: str, where: str | None = None) -> Subtype:
    """A subtype of `kind` from its key ("intersection"), id ("yielding/intersection") or paper name
    ("Intersection yielding"), case-insensitively."""
    kind = kind if isinstance(kind, InteractionType) else parse_type(kind, where)
    wanted = _norm(text.split("/", 1)[1] if text.startswith(f"{kind.value}/") else text)
    for sub in subtypes_of(kind):
        if wanted in (_norm(sub.key), _norm(sub.name)):
            return sub
    known = ", ".join(s.key for s in subtypes_of(kind))
    raise InputError(f"unknown {kind.value} subtype {text!r}; known: {known}", where=where)


# ---------------------------------------------------------------- single-agent labels

VEHICLES = frozenset({AgentType.VEHICLE})
VRUS = frozenset({AgentType.PEDESTRIAN, AgentType.CYCLIST})

LANE_POSITIONS = ("leftmost", "middle", "rightmost", "single")
"""Values of the `lane_position` label and of `changing_lanes`'s `from`/`to` ("single": a one-lane road)."""


@dataclass(frozen=True)
class LabelDef:
    """A single-agent label: `key` is stored in label files, `name` is the paper's wording, `params`
    names the values the label carries (e.g. `from`/`to` of a lane change), `applies_to` the agent types."""

    key: str
    name: str
    applies_to: frozenset[AgentType]
    params: tuple[str, ...] = ()


SINGLE_AGENT_LABELS: tuple[LabelDef, ...] = (
    LabelDef("parked", "parked", VEHICLES),
    LabelDef("off_main_road", "off the main roads", VEHICLES),
    LabelDef("static", "static", VEHICLES | VRUS),
    LabelDef("moving_slowly", "moving slowly", VEHICLES),
    LabelDef("speeding_up", "speeding up", VEHICLES),
    LabelDef("slowing_down", "slowing down", VEHICLES),
    LabelDef("constant_speed", "moving at a constant speed", VEHICLES),
    LabelDef("turning_right", "turning right", VEHICLES),
    LabelDef("turning_left", "turning left", VEHICLES),
    LabelDef("going_straight", "going straight", VEHICLES),
    LabelDef("crossing_intersection", "crossing an intersection", VEHICLES),
    LabelDef("approaching_intersection", "approaching an intersection", VEHICLES),
    LabelDef("lane_position", "lane position", VEHICLES, ("position",)),
    LabelDef("changing_lanes", "changing lanes", VEHICLES, ("from", "to")),
    LabelDef("pulling_over", "pulling over and stopping", VEHICLES),  # not in the paper's list
    LabelDef("crossing_street", "crossing the street", VRUS),
    LabelDef("walking_along_road", "walking along the road", VRUS),
    LabelDef("moving", "moving", VRUS),
)

LABELS_BY_KEY: Mapping[str, LabelDef] = MappingProxyType({d.key: d for d in SINGLE_AGENT_LABELS})


def label_def(key: str, where: str | None = None) -> LabelDef:
    """The definition of single-agent label `key`; an unknown key raises InputError listing the known."""
    try:
        return LABELS_BY_KEY[key]
    except KeyError:
        raise InputError(
            f"unknown single-agent label {key!r}; known: {', '.join(LABELS_BY_KEY)}", where=where
        ) from None


def check_params(key: str, params: Mapping[str, str], where: str | None = None) -> None:
    """Raise InputError unless `params` has exactly the values label `key` needs, each valid."""
    definition = label_def(key, where)
    if set(params) != set(definition.params):
        raise InputError(f"label {key!r} takes parameters {list(definition.params)}, got {sorted(params)}", where=where)
    for name, value in params.items():
        if key in ("lane_position", "changing_lanes") and value not in LANE_POSITIONS:
            raise InputError(
                f"label {key!r}: {name} must be one of {', '.join(LANE_POSITIONS)}, got {value!r}", where=where
            )
