"""What lies ahead of an agent on the lane graph: where it is (`AgentOnLane`), the branches of the next junction
(`junction_ahead`) and the stations of its road ahead (`stations_ahead`). Feasibility and targets both read these
(`targets.derive`), so "feasible" and "has a target" answer from one search (docs/interdrive.md, 'Targets and
feasibility')."""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.targets.config import CounterfactualConfig
from langtraj.roads import SEGMENT_SPACING_M, MapIndex
from langtraj.roads.position import AgentOnLane

JUNCTION_ENTRY_M = 5.0
"""An agent less than this far into a junction lane may yet take any branch its entry lane leads to (m)."""


# ---------------------------------------------------------------------------------------------- junctions


@dataclass(frozen=True)
class Branch:
    """One way through the next junction: its `lanes` from the agent's own (first) through the junction lanes,
    the heading change still to make along them (`turn`, rad, left positive, not wrapped) and the distance from the
    agent to the junction's exit (`exit_at`, m)."""

    lanes: tuple[int, ...]
    turn: float
    exit_at: float


@dataclass(frozen=True)
class JunctionAhead:
    """The branches of the next junction the lane graph reaches within the search, and whether some path ends
    (a lane without exits) before the search's reach without a junction (`ends`: the map stops there)."""

    branches: tuple[Branch, ...]
    ends: bool


def junction_ahead(index: MapIndex, here: AgentOnLane, reach: float, config: CounterfactualConfig) -> JunctionAhead:
    """The branches of the next junction from `here` within `reach` m (needs lanes, lane connectivity and the agent
    on a lane).

    On a junction lane the agent is inside a junction: just past its start (`JUNCTION_ENTRY_M`), every branch of
    its entry lane is still open; farther in, its branch is taken and what is left of its turn counts, unless that
    turn is (nearly) done, in which case the next junction is the one after this."""
    lane, station = here.lane, here.station
    if not index.is_junction[lane]:
        return _first_junctions(index, [((lane,), -station)], reach)
    if station <= JUNCTION_ENTRY_M:
        siblings = {x for e in index.entries[lane] for x in index.exits[e] if index.is_junction[x]} | {lane}
        return JunctionAhead(
            tuple(
                Branch(tuple(chain), branch_turn(index, chain), _length(index, chain) - station)
                for x in sorted(siblings)
                for chain in junction_chains(index, x)
            ),
            False,
        )
    branches: list[Branch] = []
    onward: list[tuple[tuple[int, ...], float]] = []
    ends = False
    for chain in junction_chains(index, lane):
        left, whole = branch_turn(index, chain, station), branch_turn(index, chain)
        direction = branch_direction(left, config)
        done = _length(index, chain) - station
        if direction in (Behaviour.TURN_LEFT, Behaviour.TURN_RIGHT) or branch_direction(whole, config) == direction:
            branches.append(Branch(tuple(chain), left, done))  # the turn is under way (or straight): this junction
            continue
        onward += [((*chain, e), done) for e in index.exits[chain[-1]]]
        ends |= not index.exits[chain[-1]] and done < reach
    if onward:
        later = _first_junctions(index, onward, reach)
        branches += later.branches
        ends |= later.ends
    return JunctionAhead(tuple(branches), ends)


def _length(index: MapIndex, lanes: list[int] | tuple[int, ...]) -> float:
    return float(sum(index.lane_lengths[x] for x in lanes))


def _first_junctions(index: MapIndex, seeds: list[tuple[tuple[int, ...], float]], reach: float) -> JunctionAhead:
    """The junction branches first reached from non-junction lanes, nearest first: `seeds` are the lanes so far
    (the last one to go on from) and the distance from the agent to the last one's start."""
    branches: list[Branch] = []
    ends = False
    heap = [(start, lanes) for lanes, start in seeds]
    heapq.heapify(heap)
    seen = {lanes[-1] for lanes, _ in seeds}
    while heap:
        start, lanes = heapq.heappop(heap)
        current = lanes[-1]
        end = start + float(index.lane_lengths[current])
        if not index.exits[current] and end < reach:
            ends = True
        if end > reach:
            continue
        for nxt in index.exits[current]:
            if nxt in seen:
                continue
            seen.add(nxt)
            if index.is_junction[nxt]:
                for chain in junction_chains(index, nxt):
                    exit_at = max(end, 0.0) + _length(index, chain)
                    branches.append(Branch((*lanes, *chain), branch_turn(index, chain), exit_at))
            else:
                heapq.heappush(heap, (end, (*lanes, nxt)))
    return JunctionAhead(tuple(branches), ends)


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


# ---------------------------------------------------------------------------------------------- the road ahead


@dataclass(frozen=True)
class StationAhead:
    """A point of the agent's road ahead: `lane` (not a junction lane), `station` on it, and the `distance` along
    the lane graph from the agent (m)."""

    lane: int
    station: float
    distance: float


def stations_ahead(
    index: MapIndex, here: AgentOnLane, reach: float, config: CounterfactualConfig
) -> list[StationAhead]:
    """Stations every `neighbour_step_m` along the agent's lane and the non-junction lanes after it, up to the next
    junction or `reach`, nearest first; from a junction lane, along the lanes its branches lead to."""
    seeds = [(0.0, here.lane, here.station)]
    if index.is_junction[here.lane]:
        seeds = [
            (_length(index, chain) - here.station, e, 0.0)
            for chain in junction_chains(index, here.lane)
            for e in index.exits[chain[-1]]
        ]
    out: list[StationAhead] = []
    heap = list(seeds)
    heapq.heapify(heap)
    seen = {lane for _, lane, _ in seeds}
    while heap:
        done, lane, station = heapq.heappop(heap)
        if index.is_junction[lane]:
            continue
        length = float(index.lane_lengths[lane])
        for s in np.arange(station, length + 1e-9, config.neighbour_step_m):
            if done + s - station > reach:
                break
            out.append(StationAhead(lane, float(s), done + float(s) - station))
        travelled = done + length - station
        for nxt in index.exits[lane]:
            if travelled <= reach and nxt not in seen:
                seen.add(nxt)
                heapq.heappush(heap, (travelled, nxt, 0.0))
    return sorted(out, key=lambda p: p.distance)
