"""Every off-road and collision event of closed-loop rollouts, sorted by cause (issue 45), so a table can say
where the realism table's offroad and collision rates come from (docs/experiments.md, 'Samples that stay on the
road').

The events are exactly those the rates count, found by the one event rule of `metrics.controllability`
(`offroad_first_steps`, `collision_events`): each (rollout, vehicle) pair off road and each (rollout, agent) pair
that collides is one event at its first off-road (or touching) future step 0..79, with the point where it happens
(the agent's box centre) and, for a collision, the agent it touches then (the deepest contact). So the shares per
cause, over the same denominators, sum to `offroad_rate` and `collision_rate` of the same rollouts.

Each event gets one cause, the first of these that holds (offroad: `OFFROAD_CAUSES`, collisions:
`COLLISION_CAUSES`, in this order):

- `no_road_edges` (offroad): the scene has no road edges offroad is measured against (`SceneMap.road_edges` is
  None: a map without edges of its own, nuScenes via ScenarioNet, where the metrics derive none from its lanes), so
  offroad is not measured. No event is made; `offroad:no_road_edges` is the share of the window's (rollout,
  vehicle) pairs left unmeasured (1 on such a map, where every other offroad share is NaN as `offroad_rate` is; 0
  elsewhere), and it is not part of the sum.
- `map_ends` (offroad): the event point is farther than `MAP_END_DISTANCE_M` from every road edge offroad is
  measured against and from every lane centreline (bike lanes included): the vehicle has driven on past where the
  mapped road ends (a window's map is cropped 30 m beyond the logged paths), so the edge it crossed is an artefact
  of the crop.
- `parked_moved`: the agent was parked (`sim.parked.parked_in_history`: from the history only) and the rollout
  has moved it more than `PARKED_MOVED_M` from its current position by the event step; for a collision, either
  agent of the pair.
- `log_overlap` (collisions): the pair's boxes already overlap at the current step of the log (the same rounded
  boxes and threshold as the collision rate): no simulation could have avoided it.
- `pedestrian_group` (collisions): both are pedestrians, or a pedestrian and a cyclist, walking together at the
  current step: centres at most `GROUP_DISTANCE_M` apart and logged velocities at most `GROUP_SPEED_DIFF_MPS`
  apart (people walking side by side touch as boxes).
- `roundabout_or_junction`: the drivable lane nearest to the event point (within `LANE_RADIUS_M`) is a junction
  lane (`MapIndex.is_junction`; for a collision, nearest to either agent's centre); for offroad also a box with a
  corner inside a roundabout or traffic island: a closed ring of the measured road edges that keeps the road
  outside it (clockwise) and spans at most `ISLAND_MAX_EXTENT_M`.
- `lane_change`: a vehicle that, at the event step, is beside its start lane (the lane matched at the current
  step, as the labeler matches lanes, or a lane downstream of it, `DOWNSTREAM_HOPS` links at most) more than
  `LANE_CHANGE_LATERAL_M` off its centre, toward a neighbour lane on that side (`MapIndex.lanes_beside`): it has
  moved into the next lane rather than on along its own; for a collision, either vehicle of the pair.
- `drift` (offroad): otherwise: the vehicle drifted off its lane across a road edge.
- `other` (collisions): otherwise (rear-end, crossing paths, ...).

Nothing here reads the logged future: the causes use the history, the current step and the rollouts.
`log_breakdown` runs the same analysis on the logged future itself, the floor a simulation is compared with.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from typing import Literal

import numpy as np
from matplotlib.path import Path as MplPath

from langtraj.errors import InputError
from langtraj.interdrive.heuristics.config import HeuristicConfig
from langtraj.metrics.controllability import collision_events, offroad_first_steps
from langtraj.metrics.features import COLLISION_THRESHOLD, SceneMap
from langtraj.metrics.interaction import pair_signed_distance
from langtraj.metrics.road import (
    CYCLIC_TOLERANCE_M2,
    RoadEdges,
    box_bottom_corners,
)
from langtraj.polylines import project_on_segments
from langtraj.roads import MapIndex
from langtraj.rollouts.baselines import generate_baseline
from langtraj.rollouts.container import Rollouts
from langtraj.rollouts.validation import check_rollouts
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType, StateField
from langtraj.sim.parked import parked_in_history

OFFROAD_CAUSES = ("no_road_edges", "map_ends", "parked_moved", "roundabout_or_junction", "lane_change", "drift")
"""The causes of an off-road event, in order of precedence."""
COLLISION_CAUSES = ("parked_moved", "log_overlap", "pedestrian_group", "roundabout_or_junction", "lane_change", "other")
"""The causes of a collision event, in order of precedence."""
CAUSES = ("no_road_edges", "map_ends", "parked_moved", "log_overlap", "pedestrian_group", "roundabout_or_junction",
          "lane_change", "drift", "other")  # fmt: skip
"""Every cause, in the order of precedence of the module docstring."""
BREAKDOWN_KEYS = tuple(f"offroad:{c}" for c in OFFROAD_CAUSES) + tuple(f"collision:{c}" for c in COLLISION_CAUSES)
"""The keys of `cause_breakdown`."""

MAP_END_DISTANCE_M = 5.0
"""An off-road point farther than this from every road edge and lane centreline lies beyond the mapped road."""
PARKED_MOVED_M = 1.0
"""A parked agent moved farther than this from its current position has been moved by the simulation (the labeler's
`parked_max_displacement`)."""
GROUP_DISTANCE_M = 2.0
"""Pedestrians (or a pedestrian and a cyclist) whose centres are at most this far apart walk together."""
GROUP_SPEED_DIFF_MPS = 1.0
"""... when their logged velocities differ by at most this (m/s)."""
LANE_RADIUS_M = 5.0
"""The junction lane nearest to an event point lies within this."""
ISLAND_MAX_EXTENT_M = 80.0
"""A closed clockwise road-edge ring at most this wide (bounding box) is an island, not a city block."""
LANE_CHANGE_LATERAL_M = 1.2
"""A vehicle farther than this from its lane's centre toward a neighbour lane is changing into it: a 2-m wide car
then reaches 0.45 m over the line of a 3.5-m lane, about where side-by-side cars on neighbour lanes touch."""
DOWNSTREAM_HOPS = 8
"""Lanes at most this many exit links from the start lane are the start lane's own road ahead."""

Kind = Literal["offroad", "collision"]


@dataclass(frozen=True)
class FailureEvent:
    """One off-road or collision event: agent `agent_id` in rollout `rollout`, first at future step `step`
    (0..79, scenario step `current_index + 1 + step`), at `xy` (its box centre), touching `partner_id` (a
    collision; None for offroad), with its `cause`."""

    kind: Kind
    rollout: int
    agent_id: int
    partner_id: int | None
    step: int
    cause: str
    xy: tuple[float, float]

    def to_dict(self) -> dict:
        return {
            "kind": self.kind,
            "rollout": self.rollout,
            "agent_id": self.agent_id,
            "partner_id": self.partner_id,
            "step": self.step,
            "cause": self.cause,
            "xy": list(self.xy),
        }


@dataclass(frozen=True)
class FailureReport:
    """Every event of one scene's rollouts and the pairs the rates count them over: `offroad_pairs` (rollout,
    vehicle) pairs where offroad is measured, `unmeasured_pairs` where it is not (no road edges), and
    `collision_pairs` (rollout, sim agent) pairs."""

    scenario_id: str
    events: tuple[FailureEvent, ...]
    offroad_pairs: int
    unmeasured_pairs: int
    collision_pairs: int

    def counts(self, kind: Kind) -> dict[str, int]:
        """Events of `kind` per cause (every cause of that kind, 0 where none)."""
        causes = OFFROAD_CAUSES if kind == "offroad" else COLLISION_CAUSES
        found = Counter(e.cause for e in self.events if e.kind == kind)
        return {c: found[c] for c in causes}

    @property
    def offroad_rate(self) -> float:
        """The share of (rollout, vehicle) pairs that leave the road (`offroad_rate`; NaN where not measured)."""
        found = sum(e.kind == "offroad" for e in self.events)
        return found / self.offroad_pairs if self.offroad_pairs else math.nan

    @property
    def collision_rate(self) -> float:
        """The share of (rollout, agent) pairs that collide (`collision_rate`)."""
        found = sum(e.kind == "collision" for e in self.events)
        return found / self.collision_pairs if self.collision_pairs else math.nan

    def shares(self) -> dict[str, float]:
        """`cause_breakdown`: per cause the share of the pairs (see the module docstring; NaN where no pair is
        measured)."""
        out: dict[str, float] = {}
        for cause, count in self.counts("offroad").items():
            if cause == "no_road_edges":
                total = self.offroad_pairs + self.unmeasured_pairs
                value = self.unmeasured_pairs / total if total else math.nan
            else:
                value = count / self.offroad_pairs if self.offroad_pairs else math.nan
            out[f"offroad:{cause}"] = value
        for cause, count in self.counts("collision").items():
            out[f"collision:{cause}"] = count / self.collision_pairs if self.collision_pairs else math.nan
        return out

    def to_dict(self) -> dict:
        return {
            "scenario_id": self.scenario_id,
            "offroad_pairs": self.offroad_pairs,
            "unmeasured_pairs": self.unmeasured_pairs,
            "collision_pairs": self.collision_pairs,
            "offroad": None if math.isnan(self.offroad_rate) else self.offroad_rate,
            "collision": None if math.isnan(self.collision_rate) else self.collision_rate,
            "shares": {k: (None if math.isnan(v) else v) for k, v in self.shares().items()},
            "events": [e.to_dict() for e in self.events],
        }


@dataclass(frozen=True, eq=False)
class FailureScene:
    """What the causes need of one scene, whatever the rollouts: built once and shared by every method's rollouts
    (`build`)."""

    scenario: Scenario
    scene_map: SceneMap
    map_index: MapIndex
    parked: np.ndarray  # bool [A], `parked_in_history`
    start_lanes: np.ndarray  # int64 [A], each vehicle's lane at the current step (-1: none, or no vehicle)
    islands: tuple[MplPath, ...]  # closed clockwise road-edge rings (roundabout and traffic islands)

    @classmethod
    def build(
        cls, scenario: Scenario, scene_map: SceneMap | None = None, config: HeuristicConfig | None = None
    ) -> FailureScene:
        """The scene's map queries, parked agents, start lanes and islands (`scene_map`: the metrics' one, if
        built already; `config`: the labeler's thresholds, lane matching and parked decision)."""
        config = config or HeuristicConfig()
        index = MapIndex.build(scenario.road_map, infer_neighbors=True)
        agents, now = scenario.agents, scenario.current_index
        lanes = np.full(scenario.num_agents, -1, np.int64)
        vehicles = np.flatnonzero(agents.valid[:, now] & (agents.types == AgentType.VEHICLE))
        if len(vehicles) and index.has_lanes:
            match = index.match_lanes(
                agents.xy[vehicles, now].astype(np.float64),
                agents.heading[vehicles, now].astype(np.float64),
                radius=config.lane_match_radius,
                max_heading_diff=config.lane_match_max_heading,
            )
            lanes[vehicles] = match.lane
        scene_map = scene_map or SceneMap.from_scenario(scenario)
        return cls(
            scenario=scenario,
            scene_map=scene_map,
            map_index=index,
            parked=parked_in_history(scenario, config, index),
            start_lanes=lanes,
            islands=() if scene_map.road_edges is None else _islands(scene_map.road_edges.edges),
        )

    # ------------------------------------------------------------------ the causes' tests
    def beyond_map(self, xy: np.ndarray) -> bool:
        """`map_ends`: farther than `MAP_END_DISTANCE_M` from every measured road edge and lane centreline."""
        point = np.asarray(xy, np.float64).reshape(1, 2)
        if self.scene_map.road_edges is not None:
            edges = self.scene_map.road_edges.edges
            if project_on_segments(point, edges.start[:, :2], edges.end[:, :2]).distance.min() <= MAP_END_DISTANCE_M:
                return False
        return not self.map_index.match_lanes(point, radius=MAP_END_DISTANCE_M, drivable_only=False).matched[0]

    def in_junction(self, xy: np.ndarray) -> bool:
        """The drivable lane nearest to `xy` (within `LANE_RADIUS_M`) is a junction lane."""
        if not self.map_index.has_lanes:
            return False
        lane = int(self.map_index.match_lanes(np.asarray(xy, np.float64), radius=LANE_RADIUS_M).lane[0])
        return lane >= 0 and bool(self.map_index.is_junction[lane])

    def on_island(self, corners: np.ndarray) -> bool:
        """A corner of a box (`corners` [4, 2]) lies inside a roundabout or traffic island (see `_islands`)."""
        points = np.asarray(corners, np.float64).reshape(-1, 2)
        return any(bool(island.contains_points(points).any()) for island in self.islands)

    def changed_lane(self, track: int, xy: np.ndarray) -> bool:
        """`lane_change`: vehicle `track` at `xy` is beside its start lane's road (the lane or one downstream)
        more than `LANE_CHANGE_LATERAL_M` off its centre, toward a neighbour lane on that side."""
        start = int(self.start_lanes[track])
        if start < 0:
            return False
        index = self.map_index
        point = np.asarray(xy, np.float64).reshape(1, 2)
        best: tuple[float, int, float, float] | None = None
        for lane in _downstream(index, start):
            station, lateral = (float(v[0]) for v in index.project_to_lane(lane, point))
            if math.isfinite(lateral) and (best is None or abs(lateral) < best[0]):
                best = (abs(lateral), lane, station, lateral)
        if best is None:
            return False
        _, lane, station, lateral = best
        beside = 0.0 < station < float(index.lane_lengths[lane])  # not past either end of the lanes
        if not beside or abs(lateral) <= LANE_CHANGE_LATERAL_M:
            return False
        return bool(index.lanes_beside(lane, station, "left" if lateral > 0 else "right", with_ending=True))

    def overlapped_in_log(self, a: int, b: int) -> bool:
        """`log_overlap`: tracks `a` and `b` touch at the current step of the log."""
        now = self.scenario.current_index
        sa, sb = (self.scenario.agents.states[t, now].astype(np.float64) for t in (a, b))
        fields = (StateField.X, StateField.Y, StateField.HEADING, StateField.LENGTH, StateField.WIDTH)
        gap = pair_signed_distance(*(sa[f] for f in fields), *(sb[f] for f in fields))
        return bool(gap < COLLISION_THRESHOLD)

    def walk_together(self, a: int, b: int) -> bool:
        """`pedestrian_group`: two pedestrians, or a pedestrian and a cyclist, side by side at the current step."""
        agents, now = self.scenario.agents, self.scenario.current_index
        types = {int(agents.types[a]), int(agents.types[b])}
        people = {int(AgentType.PEDESTRIAN), int(AgentType.CYCLIST)}
        if not (types <= people and int(AgentType.PEDESTRIAN) in types):
            return False
        apart = float(np.linalg.norm(agents.xy[a, now] - agents.xy[b, now]))
        speed_gap = float(np.linalg.norm(agents.velocity[a, now] - agents.velocity[b, now]))
        return apart <= GROUP_DISTANCE_M and speed_gap <= GROUP_SPEED_DIFF_MPS


def _islands(edges: RoadEdges) -> tuple[MplPath, ...]:
    """The measured road-edge polylines that close on themselves (ends within the metrics' cyclic tolerance), run
    clockwise (the road, on their left, lies outside) and span at most `ISLAND_MAX_EXTENT_M`: roundabout and traffic
    islands. A polyline's segments follow one another in `edges`, each linked to the one before (`prior`)."""
    found = []
    first = np.flatnonzero(edges.prior != np.arange(edges.num_segments) - 1)
    for begin, stop in zip(first.tolist(), [*first[1:].tolist(), edges.num_segments], strict=True):
        ring = np.concatenate([edges.start[begin:stop, :2], edges.end[stop - 1 : stop, :2]])
        if len(ring) < 4 or ((ring[0] - ring[-1]) ** 2).sum() >= CYCLIC_TOLERANCE_M2:
            continue
        area = 0.5 * float((ring[:-1, 0] * ring[1:, 1] - ring[1:, 0] * ring[:-1, 1]).sum())
        if area < 0 and float((ring.max(axis=0) - ring.min(axis=0)).max()) <= ISLAND_MAX_EXTENT_M:
            found.append(MplPath(ring))
    return tuple(found)


def _downstream(index: MapIndex, lane: int) -> list[int]:
    """`lane` and the lanes reachable from it over at most `DOWNSTREAM_HOPS` exit links, nearest first."""
    seen, frontier = [lane], [lane]
    for _ in range(DOWNSTREAM_HOPS):
        frontier = [e for x in frontier for e in index.exits[x] if e not in seen]
        frontier = list(dict.fromkeys(frontier))
        if not frontier:
            break
        seen.extend(frontier)
    return seen


# ---------------------------------------------------------------------------------------------- events


def _poses(rollouts: Rollouts) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return tuple(getattr(rollouts, f).astype(np.float64) for f in ("x", "y", "z", "heading"))  # type: ignore[return-value]


def _moved(scene: FailureScene, x: np.ndarray, y: np.ndarray, track: int, rollout: int, col: int, step: int) -> bool:
    """Whether the rollout has moved `track` more than `PARKED_MOVED_M` from its current position by `step`."""
    start = scene.scenario.agents.xy[track, scene.scenario.current_index].astype(np.float64)
    path = np.stack([x[rollout, col, : step + 1], y[rollout, col, : step + 1]], -1)
    return float(np.linalg.norm(path - start, axis=-1).max()) > PARKED_MOVED_M


def _offroad_events(
    scene: FailureScene, rollouts: Rollouts, tracks: np.ndarray, sizes: np.ndarray
) -> tuple[list[FailureEvent], int, int]:
    """The off-road events (exactly `offroad_flags`' pairs), the measured and the unmeasured pair counts."""
    scenario = scene.scenario
    vehicles = np.flatnonzero(scenario.agents.types[tracks] == AgentType.VEHICLE)
    pairs = rollouts.num_rollouts * len(vehicles)
    if not len(vehicles):
        return [], 0, 0
    if scene.scene_map.road_edges is None:
        return [], 0, pairs
    ids, first = offroad_first_steps(scenario, rollouts, scene_map=scene.scene_map)
    column = {int(i): c for c, i in enumerate(rollouts.object_id)}
    cols = np.array([column[int(i)] for i in ids], np.int64)
    rollout, which = np.nonzero(first >= 0)
    if not len(rollout):
        return [], pairs, 0
    x, y, z, heading = _poses(rollouts)
    chosen, first = cols[which], first[rollout, which]
    length, width, height = (
        np.broadcast_to(sizes[chosen, k, None], (len(chosen), rollouts.num_steps)) for k in range(3)
    )
    pose = [v[rollout, chosen] for v in (x, y, z, heading)]  # [P, T] each, the same boxes `offroad_flags` measures
    events = []
    for p, (r, col, step) in enumerate(zip(rollout.tolist(), chosen.tolist(), first.tolist(), strict=True)):
        track = int(tracks[col])
        xy = np.array([x[r, col, step], y[r, col, step]])
        box = [v[p, step] for v in (*pose, length, width, height)]
        if scene.beyond_map(xy):
            cause = "map_ends"
        elif scene.parked[track] and _moved(scene, x, y, track, r, col, step):
            cause = "parked_moved"
        elif scene.in_junction(xy) or scene.on_island(box_bottom_corners(*box)[:, :2]):
            cause = "roundabout_or_junction"
        elif scene.changed_lane(track, xy):
            cause = "lane_change"
        else:
            cause = "drift"
        events.append(FailureEvent("offroad", r, int(rollouts.object_id[col]), None, step, cause, _point(xy)))
    return events, pairs, 0


def _collision_events(scene: FailureScene, rollouts: Rollouts, tracks: np.ndarray) -> list[FailureEvent]:
    """The collision events: exactly `collision_flags`' (rollout, agent) pairs, as `collision_events` finds them."""
    x, y, _, _ = _poses(rollouts)
    column = {int(i): c for c, i in enumerate(rollouts.object_id)}
    events = []
    for event in collision_events(scene.scenario, rollouts):
        r, col, partner, step = event.rollout, column[event.agent], column[event.other], event.step
        a, b = int(tracks[col]), int(tracks[partner])
        here = np.array([x[r, col, step], y[r, col, step]])
        there = np.array([x[r, partner, step], y[r, partner, step]])
        if any(scene.parked[t] and _moved(scene, x, y, t, r, c, step) for t, c in ((a, col), (b, partner))):
            cause = "parked_moved"
        elif scene.overlapped_in_log(a, b):
            cause = "log_overlap"
        elif scene.walk_together(a, b):
            cause = "pedestrian_group"
        elif scene.in_junction(here) or scene.in_junction(there):
            cause = "roundabout_or_junction"
        elif scene.changed_lane(a, here) or scene.changed_lane(b, there):
            cause = "lane_change"
        else:
            cause = "other"
        ids = rollouts.object_id
        events.append(FailureEvent("collision", r, int(ids[col]), int(ids[partner]), step, cause, _point(here)))
    return events


def _point(xy: np.ndarray) -> tuple[float, float]:
    return float(xy[0]), float(xy[1])


# ---------------------------------------------------------------------------------------------- entry points


def classify_failures(scenario: Scenario, rollouts: Rollouts, *, scene: FailureScene | None = None) -> FailureReport:
    """Every off-road and collision event of `rollouts`, each with its cause (the module docstring's rules);
    `scene` (`FailureScene.build(scenario)`) may be passed to share it between several rollouts of the scene."""
    tracks = check_rollouts(scenario, rollouts)
    scene = scene or FailureScene.build(scenario)
    if scene.scenario.scenario_id != scenario.scenario_id:
        raise InputError(
            f"the failure scene is of {scene.scenario.scenario_id}, not {scenario.scenario_id}", where="scene"
        )
    now = scenario.current_index
    sizes = scenario.agents.states[tracks, now][:, [StateField.LENGTH, StateField.WIDTH, StateField.HEIGHT]]
    sizes = sizes.astype(np.float64)  # the box over the whole future: the current step's, as the rates take it
    offroad, measured, unmeasured = _offroad_events(scene, rollouts, tracks, sizes)
    collisions = _collision_events(scene, rollouts, tracks)
    return FailureReport(
        scenario_id=scenario.scenario_id,
        events=tuple(offroad + collisions),
        offroad_pairs=measured,
        unmeasured_pairs=unmeasured,
        collision_pairs=rollouts.num_rollouts * rollouts.num_agents,
    )


def cause_breakdown(scenario: Scenario, rollouts: Rollouts, *, scene: FailureScene | None = None) -> dict[str, float]:
    """Per cause, the share of (rollout, vehicle) pairs that leave the road for it (`offroad:CAUSE`) and of
    (rollout, agent) pairs that collide for it (`collision:CAUSE`), keys `BREAKDOWN_KEYS`: the denominators of
    `offroad_rate` and `collision_rate`, so the shares of the event causes sum to them."""
    return classify_failures(scenario, rollouts, scene=scene).shares()


def log_rollouts(scenario: Scenario) -> Rollouts:
    """The logged future as one rollout (log replay, `rollouts.baselines`): it reads the future, and says so
    (`Rollouts.log_following_ids`)."""
    return generate_baseline("log_replay", scenario, 1)


def log_breakdown(scenario: Scenario, *, scene: FailureScene | None = None) -> dict[str, float]:
    """`cause_breakdown` of the logged future itself (reads the future): the floor of each cause, what the log's
    own boxes and paths give on this map."""
    return cause_breakdown(scenario, log_rollouts(scenario), scene=scene)
