"""Counterfactual prompts: the behaviours the map lets an agent do instead of what it did in the log.

The behaviour kinds are those of `interdrive.behaviour`. For one agent of a scene, `behaviour_feasibility`
decides from the map which single-agent behaviours it can do (turns: the directions its lane reaches through
lane connectivity at the next junction; lane changes: a neighbour lane on that side; pulling over: a kerb on
its right; slowing down: it moves), and says "undecided" where the map lacks what that needs (no lane
connectivity, no neighbour lists), never guessing.
`feasible_alternatives` turns the feasible behaviours, and going first or yielding in each interaction pair the
log shows, into prompts, marking those the log itself shows (ground-truth prompts). `infeasible_manoeuvres`
warns about a typed prompt asking for a turn or lane change the map does not allow.
The hand-written free-text prompts (`FreeTextPrompt`, `load_free_text_prompts`) are in `free_text`.

See docs/interdrive.md ('Counterfactual prompts and instruction following').
"""

from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.adherence import AdherenceChecker, Fact, lane_change_side
from langtraj.interdrive.behaviour import (
    BEHAVIOURS,
    Behaviour,
    Side,
    behaviour_facts,
    opposite_subtype,
)
from langtraj.interdrive.dataset import PromptEntry
from langtraj.interdrive.detector import DetectorConfig
from langtraj.interdrive.heuristics import HeuristicConfig
from langtraj.interdrive.mapindex import SEGMENT_SPACING_M, MapIndex
from langtraj.interdrive.prompts import Prompt, label_phrases, label_variants, mentions_in
from langtraj.interdrive.reader import read_prompt
from langtraj.interdrive.taxonomy import LABELS_BY_KEY
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType

Status = Literal["feasible", "infeasible", "undecided"]


# ---------------------------------------------------------------------------------------------- feasibility


@dataclass(frozen=True)
class CounterfactualConfig:
    """How far ahead the map is searched, and the labelers' settings (their turn thresholds classify junction
    lanes; they also read the log to tell which alternatives it shows). Units: m, s, rad."""

    lookahead_m: float = 60.0
    """Least distance along the lane graph searched for the next junction and for neighbour lanes (m)."""
    lookahead_s: float = 8.0
    """Or as far as the agent's current speed carries it in this time, if farther (s): the simulated horizon."""
    neighbour_step_m: float = 5.0
    """Spacing of the stations along the lanes ahead where neighbour lanes are looked for (m)."""
    u_turn_angle: float = math.radians(150.0)
    """A junction branch turning by this much or more is a U-turn, which no behaviour asks for (rad)."""
    heuristics: HeuristicConfig = field(default_factory=HeuristicConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)

    def __post_init__(self) -> None:
        for name in ("lookahead_m", "lookahead_s", "neighbour_step_m", "u_turn_angle"):
            if not getattr(self, name) > 0:
                raise ValueError(f"CounterfactualConfig.{name} must be > 0, got {getattr(self, name)!r}")


@dataclass(frozen=True)
class Feasibility:
    """Whether agent `track_id` can do single-agent `behaviour` here (`status`), and why (`reason`)."""

    track_id: int
    behaviour: Behaviour
    status: Status
    reason: str = ""


@dataclass(frozen=True)
class AgentOnLane:
    """Where an agent is at the current step: its lane (index into the map index, -1 if none), station, speed."""

    lane: int
    station: float
    speed: float

    @classmethod
    def of(cls, scenario: Scenario, agent: int, index: MapIndex, cfg: HeuristicConfig) -> AgentOnLane:
        """Agent row `agent` matched to a lane as the heuristic labeler matches vehicles."""
        agents, c = scenario.agents, scenario.current_index
        speed = float(np.hypot(*agents.velocity[agent, c]))
        back = [t for t in range(c - 5, c) if t >= 0 and agents.valid[agent, t]]
        if back:  # from positions, as the labelers measure speed (some sources leave velocities at zero)
            step = float(np.median(np.diff(scenario.timestamps))) if scenario.num_steps > 1 else 0.1
            speed = float(np.linalg.norm(agents.xy[agent, c] - agents.xy[agent, back[0]])) / ((c - back[0]) * step)
        if not index.has_lanes:
            return cls(-1, math.nan, speed)
        match = index.match_lanes(
            agents.xy[agent, c][None],
            agents.heading[agent, c : c + 1],
            radius=cfg.lane_match_radius,
            max_heading_diff=cfg.lane_match_max_heading,
        )
        return cls(int(match.lane[0]), float(match.station[0]), speed)


def behaviour_feasibility(
    scenario: Scenario, track_id: int, map_index: MapIndex, config: CounterfactualConfig | None = None
) -> dict[Behaviour, Feasibility]:
    """Whether `track_id` can do each single-agent behaviour from where it is at the current step (see the module
    docstring; docs/interdrive.md gives the rules). Pair behaviours are not decided here: they come from the
    interactions the log shows (`feasible_alternatives`)."""
    config = config or CounterfactualConfig()
    agent = scenario.agents.index_of(track_id)
    kind = AgentType(int(scenario.agents.types[agent]))
    single = [b for b, spec in BEHAVIOURS.items() if not spec.is_pair]
    if not scenario.agents.valid[agent, scenario.current_index]:
        return {b: Feasibility(track_id, b, "undecided", "it is not valid at the current step") for b in single}
    here = AgentOnLane.of(scenario, agent, map_index, config.heuristics)
    reach = max(config.lookahead_m, here.speed * config.lookahead_s)
    out: dict[Behaviour, Feasibility] = {}
    for behaviour in single:
        spec = BEHAVIOURS[behaviour]
        if kind not in LABELS_BY_KEY[str(spec.label)].applies_to:
            out[behaviour] = Feasibility(
                track_id, behaviour, "undecided", f"the labelers give {spec.label!r} to no {kind.name.lower()}"
            )
    turns = _turn_feasibility(map_index, here, reach, config)
    for behaviour, (status, reason) in turns.items():
        out.setdefault(behaviour, Feasibility(track_id, behaviour, status, reason))
    for behaviour in (Behaviour.LANE_CHANGE_LEFT, Behaviour.LANE_CHANGE_RIGHT):
        status, reason = _lane_change_feasibility(map_index, here, reach, BEHAVIOURS[behaviour].side, config)
        out.setdefault(behaviour, Feasibility(track_id, behaviour, status, reason))
    moving = here.speed > config.heuristics.static_speed + config.heuristics.min_speed_change
    status, reason = _pull_over_feasibility(map_index, here, moving, config)
    out.setdefault(Behaviour.PULL_OVER, Feasibility(track_id, Behaviour.PULL_OVER, status, reason))
    out.setdefault(
        Behaviour.SLOW_DOWN,
        Feasibility(track_id, Behaviour.SLOW_DOWN, "feasible")
        if moving
        else Feasibility(track_id, Behaviour.SLOW_DOWN, "infeasible", "it is (nearly) stopped at the current step"),
    )
    for behaviour in (Behaviour.STOP, Behaviour.SPEED_UP):
        out.setdefault(behaviour, Feasibility(track_id, behaviour, "feasible"))
    return {b: out[b] for b in single}


COMFORT_DECELERATION = 2.0
"""Comfortable braking (m/s^2): a pull-over needs room to stop this way before the next junction, and a stop
target lies where it brings the agent to rest (`targets`)."""


def _pull_over_feasibility(
    index: MapIndex, here: AgentOnLane, moving: bool, config: CounterfactualConfig
) -> tuple[Status, str]:
    """Pulling over: the agent moves, drives in the lane next to the kerb on its right (the rightmost or only
    lane), and the next junction is far enough ahead to stop before it comfortably (the labeler does not call
    a stop at a junction a pull-over)."""
    if not moving:
        return "infeasible", "it is (nearly) stopped at the current step"
    missing = _no_lane(index, here, "lane position")
    if missing is not None:
        return missing
    position = index.lane_position(here.lane, here.station)
    if position == "unknown":
        reason = (
            "the map has no lane neighbour information"
            if index.neighbor_source == "none"
            else "it is inside a junction, where lanes have no neighbours"
        )
        return "undecided", reason
    if position not in ("rightmost", "single"):
        return "infeasible", "a lane lies on its right: it is not in the lane next to the kerb"
    room = here.speed**2 / (2 * COMFORT_DECELERATION) + config.heuristics.pull_over_junction_distance
    ahead = index.distance_to_junction(here.lane, here.station) if index.has_connectivity else math.inf
    if ahead < room:
        return "infeasible", f"the next junction is {ahead:.0f} m ahead, too close to stop at the kerb before it"
    return "feasible", ""


def _no_lane(index: MapIndex, here: AgentOnLane, what: str) -> tuple[Status, str] | None:
    """Undecided when the map has no lanes or the agent is on none."""
    if not index.has_lanes:
        return "undecided", "the map has no lanes"
    if here.lane < 0:
        return "undecided", f"it is on no lane at the current step, so its {what} are unknown"
    return None


def _turn_feasibility(
    index: MapIndex, here: AgentOnLane, reach: float, config: CounterfactualConfig
) -> dict[Behaviour, tuple[Status, str]]:
    """Turns and going straight: the directions of the junction branches the agent's lane reaches."""
    turns = (Behaviour.TURN_LEFT, Behaviour.GO_STRAIGHT, Behaviour.TURN_RIGHT)
    missing = _no_lane(index, here, "junction directions")
    if missing is None and not index.has_connectivity:
        missing = "undecided", "the map has no lane connectivity to follow its lane to a junction"
    if missing is not None:
        return dict.fromkeys(turns, missing)
    turns_found, ends = _junction_turns(index, here.lane, here.station, reach, config)
    if not turns_found:
        if ends:
            why = f"its lanes end within {reach:.0f} m with no junction (the map stops there)"
            return dict.fromkeys(turns, ("undecided", why))
        none = ("infeasible", f"no junction within {reach:.0f} m along its lanes")
        return {
            Behaviour.TURN_LEFT: none,
            Behaviour.TURN_RIGHT: none,
            Behaviour.GO_STRAIGHT: ("undecided", f"no junction within {reach:.0f} m: going straight is its road"),
        }
    found = {branch_direction(turn, config) for turn in turns_found}
    words = {Behaviour.TURN_LEFT: "left turn", Behaviour.GO_STRAIGHT: "straight on", Behaviour.TURN_RIGHT: "right turn"}
    allowed = ", ".join(words[b] for b in turns if b in found) or "only U-turns or bends"
    return {
        b: ("feasible", "") if b in found else ("infeasible", f"no {words[b]} from its lane at the next junction "
                                                              f"(it allows: {allowed})")
        for b in turns
    }  # fmt: skip


_JUNCTION_ENTRY_M = 5.0
"""An agent less than this far into a junction lane may yet take any branch its entry lane leads to (m)."""


def _junction_turns(
    index: MapIndex, lane: int, station: float, reach: float, config: CounterfactualConfig
) -> tuple[list[float], bool]:
    """The heading change of each branch (chain of junction lanes) of the next junction the lane graph reaches from
    `station` on `lane` within `reach`, and whether some path ends (no exit lanes) before `reach` without one.

    On a junction lane the agent is inside a junction: just past its start, every branch of its entry lane is
    still open; farther in, its branch is taken and what is left of its turn counts, unless that turn is (nearly)
    done, in which case the next junction is the one after this."""
    if not index.is_junction[lane]:
        return _next_junction_turns(index, [(lane, -station)], reach)
    if station <= _JUNCTION_ENTRY_M:
        siblings = {x for e in index.entries[lane] for x in index.exits[e] if index.is_junction[x]} | {lane}
        return [branch_turn(index, c) for x in sorted(siblings) for c in junction_chains(index, x)], False
    turns: list[float] = []
    onward: list[tuple[int, float]] = []
    ends = False
    for chain in junction_chains(index, lane):
        left, whole = branch_turn(index, chain, station), branch_turn(index, chain)
        direction = branch_direction(left, config)
        if direction in (Behaviour.TURN_LEFT, Behaviour.TURN_RIGHT) or branch_direction(whole, config) == direction:
            turns.append(left)  # the turn is under way (or the branch is straight): this junction decides
            continue
        done = float(sum(index.lane_lengths[x] for x in chain)) - station
        onward += [(e, done) for e in index.exits[chain[-1]]]
        ends |= not index.exits[chain[-1]] and done < reach
    if onward:
        more, ends_later = _next_junction_turns(index, onward, reach)
        turns += more
        ends |= ends_later
    return turns, ends


def _next_junction_turns(index: MapIndex, seeds: list[tuple[int, float]], reach: float) -> tuple[list[float], bool]:
    """Heading changes of the junction branches first reached from non-junction lanes `seeds` (lane, distance from
    the agent to its start) within `reach`, and whether some path ends before `reach` without a junction."""
    turns: list[float] = []
    ends = False
    frontier = list(seeds)
    seen = {lane for lane, _ in seeds}
    while frontier:
        current, start = frontier.pop()
        end = start + float(index.lane_lengths[current])
        if not index.exits[current] and end < reach:
            ends = True
        for nxt in index.exits[current]:
            if end > reach or nxt in seen:
                continue
            seen.add(nxt)
            if index.is_junction[nxt]:
                turns += [branch_turn(index, c) for c in junction_chains(index, nxt)]
            else:
                frontier.append((nxt, end))
    return turns, ends


def junction_chains(index: MapIndex, lane: int, depth: int = 0) -> list[list[int]]:
    """Every chain of junction lanes that starts with junction lane `lane` (a junction lane may split further)."""
    inner = [e for e in index.exits[lane] if index.is_junction[e]]
    if not inner or depth > 8:
        return [[lane]]
    return [[lane, *rest] for e in inner for rest in junction_chains(index, e, depth + 1)]


def branch_turn(index: MapIndex, chain: list[int], station: float = 0.0) -> float:
    """Net heading change along a chain of lanes from `station` on its first lane (rad, left positive; not wrapped,
    so a U-turn reads about pi)."""
    total, last = 0.0, None
    for n, lane in enumerate(chain):
        segs = index.lanes.segments_of(lane)
        if n == 0:
            segs = segs[index.lanes.station[segs] >= station - SEGMENT_SPACING_M]
        heading = index.lanes.heading[segs]
        if not len(heading):
            continue
        if last is not None:
            total += float(wrap_angle(heading[0] - last))
        total += float(np.sum(wrap_angle(np.diff(heading))))
        last = heading[-1]
    return total


def branch_direction(turn: float, config: CounterfactualConfig) -> Behaviour | None:
    """The behaviour a branch turning by `turn` makes, by the turn labeler's thresholds; None for a bend between
    them or a U-turn."""
    cfg = config.heuristics
    if abs(turn) <= cfg.straight_max_angle:
        return Behaviour.GO_STRAIGHT
    if cfg.turn_min_angle <= abs(turn) < config.u_turn_angle:
        return Behaviour.TURN_LEFT if turn > 0 else Behaviour.TURN_RIGHT
    return None


def _lane_change_feasibility(
    index: MapIndex, here: AgentOnLane, reach: float, side: Side | None, config: CounterfactualConfig
) -> tuple[Status, str]:
    """A lane change to `side`: a lane beside the agent's on that side somewhere along its lane and the lanes
    after it up to the next junction (within `reach`), by the lane positions the labeler gives."""
    missing = _no_lane(index, here, "neighbour lanes")
    if missing is not None:
        return missing
    positions = {index.lane_position(lane, s) for lane, s in stations_ahead(index, here, reach, config)}
    wanted = {"left": ("rightmost", "middle"), "right": ("leftmost", "middle")}[str(side)]
    if positions & set(wanted):
        return "feasible", ""
    if "unknown" in positions or not positions:
        reason = (
            "the map has no lane neighbour information"
            if index.neighbor_source == "none"
            else "it is inside a junction, where lanes have no neighbours"
        )
        return "undecided", reason
    return "infeasible", f"no lane on its {side} along its road (within {reach:.0f} m)"


def stations_ahead(
    index: MapIndex, here: AgentOnLane, reach: float, config: CounterfactualConfig
) -> list[tuple[int, float]]:
    """(lane, station) every `neighbour_step_m` along the agent's lane and the non-junction lanes after it, up to
    the next junction or `reach`; from a junction lane, along the lanes it leads to."""
    out: list[tuple[int, float]] = []
    start_lanes = [(here.lane, here.station, 0.0)]
    if index.is_junction[here.lane]:
        start_lanes = [(e, 0.0, 0.0) for chain in junction_chains(index, here.lane) for e in index.exits[chain[-1]]]
    frontier, seen = list(start_lanes), {lane for lane, _, _ in start_lanes}
    while frontier:
        lane, station, done = frontier.pop()
        if index.is_junction[lane]:
            continue
        length = float(index.lane_lengths[lane])
        for s in np.arange(station, length + 1e-9, config.neighbour_step_m):
            if done + s - station > reach:
                break
            out.append((lane, float(s)))
        travelled = done + length - station
        for nxt in index.exits[lane]:
            if travelled <= reach and nxt not in seen:
                seen.add(nxt)
                frontier.append((nxt, 0.0, travelled))
    return out


# ---------------------------------------------------------------------------------------------- alternatives


@dataclass(frozen=True)
class Alternative:
    """A prompt for `track_id` asking for `behaviour` (toward `other_id` for a pair behaviour): the prompt entry
    the model is conditioned on, the facts that judge it, and whether the log shows it (`logged`: a ground-truth
    prompt; otherwise a counterfactual one)."""

    track_id: int
    behaviour: Behaviour
    prompt: PromptEntry
    facts: frozenset[Fact]
    logged: bool
    other_id: int | None = None


def make_alternative(
    behaviour: Behaviour,
    track_id: int,
    logged: frozenset[Fact],
    other_id: int | None = None,
    subtype: str | None = None,
) -> Alternative:
    """The prompt asking `track_id` for `behaviour`, marked as logged when `logged` holds all its facts."""
    spec = BEHAVIOURS[behaviour]
    facts = behaviour_facts(behaviour, track_id, other_id, subtype)
    text = spec.text(track_id, other_id)
    subtype_id = next(iter(facts))[3] if spec.is_pair else None  # type: ignore[misc]
    labels = spec.label_keys
    entry = PromptEntry.of(Prompt(text, mentions_in(text), subtype_id, labels, source="counterfactual"))
    return Alternative(track_id, behaviour, entry, facts, facts <= logged, other_id)


def logged_facts(
    scenario: Scenario, map_index: MapIndex, config: CounterfactualConfig | None = None
) -> frozenset[Fact]:
    """The facts the labelers find on the scene's logged future (what a ground-truth prompt states)."""
    config = config or CounterfactualConfig()
    return AdherenceChecker.build(scenario, config.heuristics, config.detector, map_index).logged


def feasible_alternatives(
    scenario: Scenario,
    track_id: int,
    map_index: MapIndex,
    config: CounterfactualConfig | None = None,
    *,
    logged: frozenset[Fact] | None = None,
) -> tuple[Alternative, ...]:
    """Every prompt `track_id` can follow here: each feasible single-agent behaviour (`behaviour_feasibility`),
    each single-agent behaviour the log shows (the log proves it feasible, also where the map cannot tell), and,
    for each interaction of `PAIR_SUBTYPES` the log shows between it and another agent, both going first and
    yielding, unless the order is out of reach (`targets.order_feasibility`: going first where the other agent
    gets to the crossing first however the agent speeds up, or a pedestrian is already crossing there). `logged`
    is the log's facts (`logged_facts`, computed when not given; pass them to label the scene once for all its
    agents, or add facts such as ground-truth interactions)."""
    config = config or CounterfactualConfig()
    if logged is None:
        logged = logged_facts(scenario, map_index, config)
    feasible = behaviour_feasibility(scenario, track_id, map_index, config)
    out = []
    for behaviour, verdict in feasible.items():
        alternative = make_alternative(behaviour, track_id, logged)
        if verdict.status == "feasible" or alternative.logged:
            out.append(alternative)
    agent_type = AgentType(int(scenario.agents.types[scenario.agents.index_of(track_id)]))
    pairs: dict[int, dict[Behaviour, str]] = {}
    for fact in sorted(f for f in logged if f[0] == "interaction" and f[1] == track_id):
        other, subtype = int(fact[2]), str(fact[3])
        opposite = opposite_subtype(subtype, agent_type)
        if opposite is None:
            continue
        found = Behaviour.YIELD if subtype.startswith("yielding/") else Behaviour.GO_FIRST
        flipped = Behaviour.GO_FIRST if found is Behaviour.YIELD else Behaviour.YIELD
        pairs.setdefault(other, {}).setdefault(found, subtype)
        pairs[other].setdefault(flipped, opposite)
    from langtraj.interdrive.targets import order_feasibility  # targets builds on this module's lane reading

    for other, chosen in pairs.items():
        for behaviour in (Behaviour.GO_FIRST, Behaviour.YIELD):
            alternative = make_alternative(behaviour, track_id, logged, other, chosen[behaviour])
            if alternative.logged or order_feasibility(scenario, track_id, other, behaviour, map_index).status != (
                "infeasible"
            ):
                out.append(alternative)
    return tuple(out)


# ---------------------------------------------------------------------------------------------- warnings


@dataclass(frozen=True)
class ManoeuvreWarning:
    """A typed prompt asks agent `track_id` for a `behaviour` the map does not allow, because `reason`."""

    track_id: int
    behaviour: Behaviour
    reason: str

    @property
    def message(self) -> str:
        return f"@{self.track_id} cannot {BEHAVIOURS[self.behaviour].manoeuvre}: {self.reason}"


_SIDE_WORDS = re.compile(r"\b(?:to|into|toward|towards) the (left|right)\b")


def asked_behaviours(prompt: PromptEntry) -> tuple[Behaviour, ...]:
    """The single-agent behaviours `prompt` asks of its target (the first agent it mentions): from its labels
    (turns, lane changes, stopping, pulling over, speed changes), or, for a typed prompt that carries none, the
    behaviour the prompt reader reads in its words (`interdrive.reader`). A labelled lane change asks for a side
    when its words hold a directed lane-change phrase or say "to the left/right"; otherwise for either side."""
    labels = prompt.labels
    if not labels and prompt.subtype is None:
        reading = read_prompt(prompt.text)
        single = reading.behaviour is not None and not BEHAVIOURS[reading.behaviour].is_pair
        return (reading.behaviour,) if single and reading.agent == (prompt.mentions or (None,))[0] else ()
    out = [b for b, spec in BEHAVIOURS.items() if spec.label in labels and not spec.is_lane_change]
    if "changing_lanes" in labels:
        sides = _lane_change_sides(prompt.text) or ("left", "right")
        out += [b for b, spec in BEHAVIOURS.items() if spec.is_lane_change and spec.side in sides]
    return tuple(out)


@functools.cache
def _lane_change_phrases() -> tuple[tuple[str, tuple[Side, ...]], ...]:
    """Every lane-change phrase of the phrase tables with the sides it names, longest first ("middle" to
    "middle" gives the undirected ones)."""
    out: dict[str, tuple[Side, ...]] = {}
    for key, params in label_variants():
        if key == "changing_lanes":
            side = lane_change_side(params)
            out.update({p.lower(): (side,) if side else ("left", "right") for p in label_phrases(key, params)})
    generic = label_phrases("changing_lanes", {"from": "middle", "to": "middle"})
    out.update({p.lower(): ("left", "right") for p in generic if p.lower() not in out})
    return tuple(sorted(out.items(), key=lambda item: -len(item[0])))


def _lane_change_sides(text: str) -> tuple[Side, ...]:
    """The sides a lane change in `text` may go to: those of its longest lane-change phrase, narrowed by "to the
    left/right"; empty when `text` holds no lane-change phrase."""
    lowered = " ".join(text.lower().split())
    sides = next((s for phrase, s in _lane_change_phrases() if re.search(rf"\b{re.escape(phrase)}\b", lowered)), ())
    said = {m.group(1) for m in _SIDE_WORDS.finditer(lowered)}
    if len(sides) == 2 and len(said) == 1:
        return tuple(said)  # type: ignore[return-value]
    return sides


def infeasible_manoeuvres(
    scenario: Scenario, prompt: PromptEntry, map_index: MapIndex, config: CounterfactualConfig | None = None
) -> tuple[ManoeuvreWarning, ...]:
    """A warning for each single-agent behaviour `prompt` asks of its target (`asked_behaviours`) that the map
    does not allow from where it is (`behaviour_feasibility`: a turn or lane change with no lane for it, a pull-over
    away from the kerb lane or too close to a junction, slowing down while stopped); an undecided one (no lane
    connectivity, no neighbour lists) is not warned about. A lane change that asks for no side warns only when
    neither side has a lane."""
    asked = asked_behaviours(prompt)
    if not asked or not prompt.mentions:
        return ()
    track = prompt.mentions[0]
    verdicts = behaviour_feasibility(scenario, track, map_index, config)
    changes = [b for b in asked if BEHAVIOURS[b].is_lane_change]
    if len(changes) == 2 and any(verdicts[b].status != "infeasible" for b in changes):
        asked = tuple(b for b in asked if b not in changes)
    return tuple(ManoeuvreWarning(track, b, verdicts[b].reason) for b in asked if verdicts[b].status == "infeasible")
