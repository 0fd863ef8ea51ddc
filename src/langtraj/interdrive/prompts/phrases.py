"""Phrase tables: at least 20 rephrasings of every single-agent label and every interaction subtype.

Phrases are verb phrases with the subject omitted ("speeds up", "yields to <other> at the
intersection"), in the third person singular so that any singular subject fits ("@12",
"the target agent"). Interaction phrases name the other agent with the slot `<other>`. They are
written with the template grammar of `grammar.py` and follow the definitions in `taxonomy.py`; the
paper generated its rephrasings with an LLM, here they are hand-written (see `llm.py` for an
optional LLM backend).

See docs/interdrive.md.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from langtraj.errors import InputError
from langtraj.interdrive.prompts.grammar import expand_all
from langtraj.interdrive.taxonomy import LABELS_BY_KEY, LANE_POSITIONS, SUBTYPES_BY_ID, check_params

OTHER_SLOT = "<other>"

# ---------------------------------------------------------------- single-agent labels

_LABEL_TEMPLATES: dict[str, tuple[str, ...]] = {
    "parked": (
        "{is parked|is sitting parked|remains parked|stays parked|is left parked|sits parked}"
        "[ {at the roadside|by the side of the road|at the curb|in a parking spot}]",
    ),
    "off_main_road": (
        "{is|stays|remains|keeps|is located|is travelling} "
        "{off the main road|off the main roads|away from the main roads|outside the main roadway|off the roadway}",
    ),
    "static": (
        "{is static|is stationary|is standing still|stands still|stays still|remains still|remains stationary"
        "|stays stationary|is not moving|does not move|keeps still|is motionless|remains motionless|stays in place"
        "|remains in place|is at a standstill|stays put|holds its position|doesn't move|is completely still}"
        "[ throughout]",
    ),
    "moving_slowly": (
        "{moves|drives|travels|rolls|is moving|is driving|is travelling|is rolling}"
        " {slowly|at a low speed|at a slow speed|at a slow pace|at a crawl}",
        "{creeps|crawls|inches} {along|forward}",
        "{is creeping|is crawling|is inching} {along|forward}",
    ),
    "speeding_up": (
        "{speeds up|accelerates|picks up speed|gains speed|increases its speed|is speeding up|is accelerating"
        "|is picking up speed|is gaining speed|is increasing its speed}[ {gradually|steadily}]",
    ),
    "slowing_down": (
        "{slows down|decelerates|brakes|loses speed|reduces its speed|eases off|is slowing down|is decelerating"
        "|is braking|is losing speed|is reducing its speed}[ {gradually|steadily}]",
    ),
    "constant_speed": (
        "{moves|drives|travels|cruises|is moving|is driving|is travelling|is cruising}"
        " at a {constant|steady|stable|consistent|uniform} speed",
        "{keeps|maintains|holds} {a steady|a constant|an even|its} speed",
    ),
    "turning_right": (
        "{turns|is turning|swings|steers|goes|heads} {right|to the right}",
        "{makes|is making|takes|is taking|executes} a right[-hand] turn",
        "{makes|takes|hangs} a right",
        "turns off to the right",
    ),
    "turning_left": (
        "{turns|is turning|swings|steers|goes|heads} {left|to the left}",
        "{makes|is making|takes|is taking|executes} a left[-hand] turn",
        "{makes|takes|hangs} a left",
        "turns off to the left",
    ),
    "going_straight": (
        "{goes|is going|drives|is driving|continues|keeps going|heads|is heading|travels|proceeds|carries on}"
        " straight[ ahead]",
        "{drives|keeps going|continues|travels} in a straight line",
        "{keeps|stays} on a straight course",
    ),
    "crossing_intersection": (
        "{crosses|is crossing|drives through|is driving through|goes through|is going through|passes through"
        "|is passing through|travels through|makes its way through|moves through|proceeds through}"
        " {the|an} intersection",
        "{crosses|drives through|goes through} the junction",
    ),
    "approaching_intersection": (
        "{approaches|is approaching|nears|is nearing|comes up to|is coming up to|drives toward|is driving toward"
        "|heads toward|is heading toward|gets close to|is getting close to}"
        " {the intersection|the junction|an intersection|a junction}",
    ),
    "pulling_over": (
        "{pulls over|pulls in|pulls over to the side} and {stops|comes to a stop|comes to a halt}",
        "{pulls over|pulls in|moves over|steers over} to {the side of the road|the curb|the roadside}"
        " and {stops|comes to a stop|halts}",
        "{is pulling over|is pulling in} {to stop|to the side of the road|to the curb}",
        "{stops|comes to a stop|halts} {at the side of the road|at the curb|by the roadside} after pulling over",
        "pulls over[ to the {side of the road|curb}]",
    ),
    "crossing_street": (
        "{crosses|is crossing|goes across|is going across|makes its way across|moves across|is moving across"
        "|heads across|is heading across|gets across|travels across} {the street|the road|the roadway}",
    ),
    "walking_along_road": (
        "{walks|is walking|moves|is moving|travels|is travelling|heads|is heading|goes|is going}"
        " along {the road|the street|the side of the road|the edge of the road}",
        "{walks|is walking|moves|is moving} {beside|alongside|parallel to} the road",
    ),
    "moving": (
        "{moves|is moving|keeps moving|travels|is travelling|proceeds}[ {along|forward|ahead}]",
        "{is in motion|is on the move|stays in motion|keeps going}",
    ),
}

_LANE_NOUNS = {
    "leftmost": "{the leftmost lane|the far-left lane|the left-most lane|the lane furthest to the left}",
    "middle": "{a middle lane|the middle lane|one of the middle lanes|the center lane}",
    "rightmost": "{the rightmost lane|the far-right lane|the right-most lane|the lane furthest to the right}",
}
_IN_LANE = "{drives|is driving|travels|is travelling|stays|keeps|remains|is} in "

_LANE_POSITION_TEMPLATES: dict[str, tuple[str, ...]] = {
    **{pos: (_IN_LANE + noun,) for pos, noun in _LANE_NOUNS.items()},
    "single": (
        _IN_LANE + "{the only lane|the single lane}",
        "{drives|is driving|travels|is travelling|is|stays} on"
        " {a single-lane road|a one-lane road|a road with one lane}",
    ),
}

# Lane names without the word "lane": "changes lanes from the middle to the rightmost lane".
_LANE_ADJ = {
    "leftmost": "{the leftmost|the far-left}",
    "middle": "the middle",
    "rightmost": "{the rightmost|the far-right}",
}
_LANE_ORDER = {"leftmost": 0, "middle": 1, "rightmost": 2}

_GENERIC_LANE_CHANGE = (
    "{changes lanes|is changing lanes|switches lanes|is switching lanes|makes a lane change"
    "|is making a lane change|performs a lane change}",
    "{moves|shifts|steers} {into|over into} {another|a different|an adjacent|the next} lane",
)


def _lane_change_templates(src: str, dst: str) -> tuple[str, ...]:
    side = "right" if _LANE_ORDER[dst] > _LANE_ORDER[src] else "left"
    return (
        "{changes lanes|is changing lanes|switches lanes|is switching lanes|moves|is moving|shifts|moves over}"
        f" from {_LANE_ADJ[src]}[ lane] {{to|into}} {_LANE_ADJ[dst]} lane",
        f"{{changes lanes|moves over|shifts over}} to the {side} into {_LANE_NOUNS[dst]}",
    )


def _param_label_templates(key: str, params: Mapping[str, str]) -> tuple[str, ...]:
    if key == "lane_position":
        return _LANE_POSITION_TEMPLATES[params["position"]]
    src, dst = params["from"], params["to"]
    if src == dst or "single" in (src, dst):
        return _GENERIC_LANE_CHANGE  # no meaningful direction: fall back to a plain lane change
    return _lane_change_templates(src, dst)


# ---------------------------------------------------------------- interaction subtypes

_YIELD = "yields to|gives way to|is yielding to|is giving way to"  # verbs to put in a `{...}` group
_CROSS_ROAD = "{crosses|is crossing|goes across|makes its way across|moves across|heads across} the {road|street}"

_SUBTYPE_TEMPLATES: dict[str, tuple[str, ...]] = {
    # -- lane change
    "lane_change/for_turn_or_exit": (
        "{changes lanes|switches lanes|moves over|moves into another lane} {near|alongside|close to} <other>"
        " {to prepare for a turn|to get ready to turn|in preparation for turning|to prepare for an exit"
        "|to take an exit|in preparation for exiting}",
    ),
    "lane_change/for_overtaking": (
        "{changes lanes|switches lanes|is changing lanes|moves over a lane|pulls out into the next lane"
        "|moves into the adjacent lane} to {overtake|pass|get past|get around|get ahead of} <other>",
    ),
    "lane_change/avoiding_slower_traffic": (
        "{changes lanes|switches lanes|is changing lanes|moves into another lane|moves over}"
        " to {avoid|get around|bypass|avoid being held up by|avoid getting stuck behind} <other>",
        "{changes lanes|switches lanes|moves over} because <other> ahead {is moving slowly|is too slow|is in the way}",
    ),
    "lane_change/for_merging": (
        "{changes lanes|switches lanes|is changing lanes|moves over} to merge into {the flow of traffic"
        "|the stream of traffic|the other lane} {next to|alongside} <other>",
    ),
    "lane_change/with_lead_or_trail": (
        "{changes lanes|switches lanes|moves over|is changing lanes}[ {carefully|cautiously}]"
        " {with <other> directly ahead or behind|with <other> right in front or behind"
        "|while <other> is close ahead or behind}",
    ),
    "lane_change/cut_in": (
        "{cuts in front of|cuts in ahead of|cuts in on|changes lanes right in front of|merges in front of"
        "|pulls into the lane right in front of|swerves in front of|nips in front of|squeezes in front of"
        "|slots in just ahead of|dives in front of|barges in front of} <other>",
        "{cuts off|cuts up} <other>[ {sharply|suddenly|with a lane change}]",
        "{moves|changes lanes|swerves|merges} into the lane of <other>[ {just|right}] {in front of|ahead of} it",
    ),
    # -- following / stopping behind
    "following/with_lead": (
        "{follows|is following|drives behind|is driving behind|trails|stays behind|travels behind|is travelling behind}"
        " <other>[ {at a safe distance|keeping a safe gap|while keeping its distance}]",
        "{keeps|maintains} a safe distance behind <other>",
        "adjusts its speed to follow <other>",
    ),
    "following/slow_lead": (
        "{follows|is following|trails|is trailing|drives behind|is driving behind|creeps along behind"
        "|is stuck behind|is held up behind} <other> {which is moving slowly|which is driving slowly"
        "|at a slower pace than it would like|at a reduced speed}",
        "{is held up by|is slowed down by|has to slow down for} <other> ahead",
    ),
    "following/tailgating": (
        "{tailgates|is tailgating} <other>[ {aggressively|dangerously|closely}]",
        "{follows|is following|drives|is driving|stays|keeps|travels|rides}"
        " {too close|dangerously close|far too close|aggressively close} behind <other>",
        "{rides|sits on} the bumper of <other>",
    ),
    "following/stopping_behind_lead": (
        "{stops|comes to a stop|comes to a halt|halts|pulls up|brakes to a stop|is stopping|is coming to a stop"
        "|stops and waits|waits} behind <other>[ {in the queue|in traffic}]",
    ),
    "following/stopping_behind_intersection": (
        "{stops|comes to a stop|comes to a halt|halts|pulls up|waits} behind <other>"
        " {before entering|just before|short of|before} the {intersection|junction}",
    ),
    # -- yielding
    "yielding/intersection": (
        "{" + _YIELD + "|waits for|stops for|slows down for|holds back for|is waiting for} <other>"
        " at the {intersection|junction}",
        "{lets <other> go first|gives <other> the right of way|waits for <other> to pass}"
        " at the {intersection|junction}",
    ),
    "yielding/before_merge_or_lane_change": (
        "{" + _YIELD + "|holds back for} <other> {before merging|before changing lanes"
        "|before merging or changing lanes|before moving over|when changing lanes|when merging}",
        "{waits for <other> to pass|lets <other> go by} before {merging|changing lanes}",
    ),
    "yielding/to_merging_or_lane_change": (
        "{" + _YIELD + "|makes room for|slows down for|holds back for} <other>"
        " {merging in ahead|changing lanes in front|moving over in front|merging into the current lane}",
        "lets <other> {merge in|move over in front|change lanes in front|cut in}",
    ),
    "yielding/to_pedestrian": (
        "{waits for|stops for|is waiting for|holds back for} <other> to cross[ the road]",
        "{" + _YIELD + "|slows down for|stops for} <other> {at the crosswalk|crossing the road"
        "|crossing the street|who is crossing}",
        "lets <other> cross[ the road][ safely]",
    ),
    "yielding/roundabout": (
        "{" + _YIELD + "|waits for|holds back for|is waiting for} <other> {before entering the roundabout"
        "|already in the roundabout|circulating in the roundabout|at the roundabout entrance}",
    ),
    "yielding/pedestrian_to_vehicle": (
        "{waits for <other> to pass|waits for <other> to go by|pauses to let <other> pass|stops to let <other> go by"
        "|yields to <other>|gives way to <other>|lets <other> pass|holds back for <other>}"
        " {before crossing|before crossing the road|before stepping into the road}",
        "waits at the curb until <other> has passed",
    ),
    # -- passing
    "passing/intersection_with_yielding": (
        "{drives through|goes through|passes through|crosses|proceeds through|moves through|is driving through"
        "|is going through} the {intersection|junction} {while <other> yields|while <other> gives way"
        "|as <other> gives way|while <other> waits|with <other> yielding to it|while <other> holds back}",
        "takes the right of way over <other> at the {intersection|junction}",
    ),
    "passing/pedestrian": (
        "{passes|drives past|goes past|moves past|is passing|is driving past|goes by|drives by} <other>"
        "[ {at a safe distance|keeping a safe distance|with a safe gap|giving them room}]",
    ),
    "passing/pedestrian_passing_vehicle": (
        "{walks|goes|moves|is walking|makes its way} {in front of|around} <other>"
        "[ {which is stationary|which is stopped|which is standing still}]",
        "{crosses|is crossing} in front of <other>[ {which is stationary|which is stopped|which is standing still}]",
    ),
    "passing/roundabout": (
        "{drives through|goes through|passes through|navigates|moves through|is driving through|is going through"
        "|makes its way through} the roundabout {ahead of <other>|before <other>|while <other> waits"
        "|while <other> yields|with the right of way over <other>|without stopping for <other>}",
    ),
    "passing/maintaining_speed": (
        "{keeps|maintains|holds|sticks to} {its speed|its original speed|a steady speed}"
        " {without yielding to <other>|without giving way to <other>|while passing <other>|as it goes past <other>}",
        "{continues|carries on|drives on|proceeds} at {its original speed|the same speed|a steady speed}"
        " {without yielding to <other>|past <other>}",
    ),
    "passing/as_leading_vehicle": (
        "{leads|is leading|drives in front of|is driving in front of|travels ahead of|is travelling ahead of"
        "|stays ahead of|keeps ahead of} <other>[ {which follows behind|which is following|which trails behind}]",
        "{passes through|goes ahead|drives on} with <other> following[ behind]",
    ),
    "passing/braking_lead": (
        "{brakes hard|slams on the brakes|stamps on the brakes|brakes sharply|brakes suddenly|jams on the brakes"
        "|makes an emergency stop|does an emergency stop} {in front of|right in front of|just ahead of} <other>",
        "{brake-checks|brake checks} <other>",
    ),
    "passing/red_light_running": (
        "{runs|jumps|ignores|blows through|goes through|drives through} the red light {across the path of"
        "|in front of|right in front of} <other>",
        "{crosses|enters|drives through} the intersection {on red|against the red light}"
        " {in front of|across the path of} <other>",
    ),
    "passing/vru_crossing": (
        _CROSS_ROAD + " {while <other> yields|while <other> waits|as <other> gives way|in front of <other>"
        "|ahead of <other>}",
    ),
    # -- overtaking
    "overtaking/car_avoidance": (
        "[{suddenly|quickly} ]{swerves to avoid|brakes to avoid|takes evasive action to avoid|steers around"
        "|veers away from|dodges|maneuvers to avoid|swerves around|brakes hard to avoid|speeds up to avoid"
        "|accelerates away from|steers to avoid} <other>",
        "{avoids|is avoiding|evades} <other>",
    ),
    "overtaking/standard": (
        "{overtakes|passes|gets past|goes around} <other>[ {by using the adjacent lane"
        "|and returns to its original lane|and moves back into its lane|using the next lane over}]",
        "is overtaking <other>[ {by using the adjacent lane|using the next lane over}]",
        "{pulls out|moves into the next lane|changes lanes} to {overtake|pass|get past} <other>"
        " and {returns to|moves back into|pulls back into} its original lane",
    ),
    "overtaking/high_speed": (
        "{overtakes|passes|is overtaking|is passing|gets past|goes around} <other> {at high speed"
        "|at highway speed|at high speed on the highway|quickly on the highway|on the highway at speed}",
        "{speeds past|races past|zooms past} <other>[ on the highway]",
    ),
    "overtaking/cut_in": (
        "{overtakes|passes|gets past|races past} <other> and {cuts in front of it|cuts in ahead of it|cuts it off"
        "|pulls in just ahead of it|swerves back in front of it|squeezes back in front of it}",
        "{overtakes and cuts in front of|passes and cuts in ahead of|gets past and cuts in on} <other>",
    ),
    # -- merging
    "merging/standard": (
        "{merges into|is merging into|enters|joins|slots into|pulls into} {the traffic flow|the flow of traffic"
        "|the stream of traffic} {alongside|next to} <other>[ from {the on-ramp|a merging lane}]",
    ),
    "merging/lane_reduction": (
        "{merges|is merging|moves over|shifts over} {into the lane of <other>|next to <other>|alongside <other>}"
        " {as the lane ends|because the lane ends|where the lane ends|as the road narrows"
        "|because of a lane closure}",
    ),
    "merging/zipper": (
        "{zipper merges with|zipper-merges with|takes turns merging with|alternates merging with"
        "|merges in turn with|merges alternately with|zips in with} <other>"
        "[ {where two lanes become one|into a single lane|as the lanes narrow to one}]",
    ),
    "merging/on_ramp_accelerating": (
        "{accelerates|speeds up} {onto the highway|along the on-ramp|on the on-ramp}"
        " {to merge with|to match the speed of|to merge alongside|to fit in with} <other>",
        "{merges onto|enters|joins} the highway {next to|alongside} <other>"
        " while {accelerating|speeding up|picking up speed}",
    ),
    "merging/late": (
        "{merges|is merging|squeezes in|slots in|moves over} {late|at the last moment"
        "|at the end of the merging lane|near the end of the lane|at the last possible point}"
        " {next to|alongside} <other>[ in {heavy|congested} traffic]",
    ),
    "merging/pull_out": (
        "{pulls out|pulls out right|pulls out suddenly|noses out|edges out} in front of <other>"
        "[ from {a side road|a side street|a driveway|the kerb|a parking spot}]",
        "{pulls out of|emerges from|comes out of} {a side road|a side street|a driveway|a junction}"
        " {in front of|right in front of|just ahead of} <other>",
    ),
    # -- other
    "other/undefined": (
        "{behaves unusually|acts unusually|does something unusual|behaves in an unexpected way"
        "|acts in an unexpected way|does something unexpected|makes an unusual maneuver|acts oddly|behaves oddly}"
        " {around|near|close to|next to} <other>",
    ),
    "other/no_interaction": (
        "{does not interact with|doesn't interact with|has no interaction with|is not interacting with"
        "|is not affected by|is unaffected by|does not react to|does not respond to}"
        " {any other agent|other agents|other road users|anyone else|the surrounding traffic}",
    ),
    "other/unknown": (
        "{behaves|acts|moves} in {an unclear|an ambiguous|an uncertain|an indeterminate|a hard-to-read} way",
        "does something {unclear|hard to determine|that cannot be determined|ambiguous}",
        "has an {unknown|unclear|undetermined} interaction status",
    ),
}

OTHER_FALLBACK = "another road user"
"""What `<other>` becomes when an interaction names no second agent (`other_id` -1)."""


# ---------------------------------------------------------------- lookups


def _known_labels() -> str:
    return ", ".join(LABELS_BY_KEY)


@functools.cache
def _label_phrases(key: str, params: tuple[tuple[str, str], ...]) -> tuple[str, ...]:
    if key in _LABEL_TEMPLATES:
        return tuple(expand_all(_LABEL_TEMPLATES[key]))
    return tuple(expand_all(_param_label_templates(key, dict(params))))


def label_phrases(key: str, params: Mapping[str, str] = MappingProxyType({})) -> tuple[str, ...]:
    """Every rephrasing of single-agent label `key` with `params` (e.g. `{"position": "rightmost"}`);
    an unknown key or bad params raise InputError listing what is valid."""
    if key not in LABELS_BY_KEY:
        raise InputError(f"unknown single-agent label {key!r}; known: {_known_labels()}")
    check_params(key, params)
    return _label_phrases(key, tuple(sorted(params.items())))


@functools.cache
def _interaction_phrases(subtype_id: str) -> tuple[str, ...]:
    return tuple(expand_all(_SUBTYPE_TEMPLATES[subtype_id]))


def interaction_phrases(subtype_id: str) -> tuple[str, ...]:
    """Every rephrasing of interaction subtype `subtype_id` (e.g. "yielding/intersection"), with the other
    agent as `<other>`; an unknown id raises InputError listing the known ones."""
    if subtype_id not in SUBTYPES_BY_ID or subtype_id not in _SUBTYPE_TEMPLATES:
        raise InputError(f"unknown interaction subtype {subtype_id!r}; known: {', '.join(SUBTYPES_BY_ID)}")
    return _interaction_phrases(subtype_id)


def label_variants() -> tuple[tuple[str, Mapping[str, str]], ...]:
    """Every (label key, params) with a phrase table of its own: each plain label, `lane_position` for
    each position, `changing_lanes` for each ordered pair of distinct non-single positions."""
    out: list[tuple[str, Mapping[str, str]]] = []
    for key, definition in LABELS_BY_KEY.items():
        if not definition.params:
            out.append((key, {}))
        elif key == "lane_position":
            out.extend((key, {"position": pos}) for pos in LANE_POSITIONS)
        elif key == "changing_lanes":
            lanes = [p for p in LANE_POSITIONS if p != "single"]
            out.extend((key, {"from": a, "to": b}) for a in lanes for b in lanes if a != b)
        else:  # a new parameterised label needs its own branch here (and phrases)
            raise NotImplementedError(f"no phrase variants for parameterised label {key!r}")
    return tuple(out)


def phrase_key(key: str, params: Mapping[str, str] = MappingProxyType({})) -> str:
    """The CANONICAL key of a label: `key`, or `key[name=value,...]` for parameterised labels."""
    if not params:
        return key
    return f"{key}[{','.join(f'{k}={v}' for k, v in sorted(params.items()))}]"


def _canonical() -> Mapping[str, str]:
    table = {phrase_key(key, params): label_phrases(key, params)[0] for key, params in label_variants()}
    table["changing_lanes"] = expand_all(_GENERIC_LANE_CHANGE)[0]
    table.update({sid: interaction_phrases(sid)[0] for sid in SUBTYPES_BY_ID})
    return MappingProxyType(table)


CANONICAL: Mapping[str, str] = _canonical()
"""One canonical phrase (the first expansion) per label variant (`phrase_key`), for plain
`changing_lanes`, and per interaction subtype id, for stats and plots."""


def phrase_tables() -> Mapping[str, tuple[str, ...]]:
    """Every template phrase table, keyed like `CANONICAL` (label variants by `phrase_key`, subtypes by id)."""
    tables = {phrase_key(key, params): label_phrases(key, params) for key, params in label_variants()}
    tables.update({sid: interaction_phrases(sid) for sid in SUBTYPES_BY_ID})
    return tables


@dataclass(frozen=True)
class PhraseBank:
    """The template phrases plus optional extra rephrasings (e.g. from an LLM), keyed like `CANONICAL`:
    `phrase_key(key, params)` for labels, the subtype id for interactions."""

    extra: Mapping[str, tuple[str, ...]] = field(default_factory=dict)

    def labels(self, key: str, params: Mapping[str, str] = MappingProxyType({})) -> tuple[str, ...]:
        return label_phrases(key, params) + tuple(self.extra.get(phrase_key(key, params), ()))

    def interactions(self, subtype_id: str) -> tuple[str, ...]:
        return interaction_phrases(subtype_id) + tuple(self.extra.get(subtype_id, ()))


TEMPLATES_ONLY = PhraseBank()
"""The default bank: the template grammar's phrases alone."""
