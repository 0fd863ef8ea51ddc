"""Ground-truth behaviour events from a recorded SUMO simulation (schema in docs/data.md).

Every event is a `BehaviorEvent(kind, track_id, start, end, other_id, attributes)` over global steps
[start, end). Kinds:

- `lane_change`: from SUMO's lane-change output; start at the latest manoeuvre start before the switch,
  end one past the manoeuvre's end, at most `MAX_MANOEUVRE_STEPS` either side of the switch;
  `other_id` is the leader on the target lane right after the change (or -1). Attributes: `direction`
  (left/right), `reason` (strategic, cooperative, speedGain, keepRight, or SUMO's first reason token),
  `reason_detail` (SUMO's full reason), `from_lane`, `to_lane`, `change_step`, `from_lane_ends` (the
  lane left has no onward connection: an acceleration lane or a lane drop, so the change is a merge).
- `follow`: a run of at least `MIN_FOLLOW_STEPS` steps with the same leader within 60 m. Attributes:
  `min_gap`, `mean_gap`, `start_gap`, `end_gap` (m, bumper to bumper).
- `yield`: SUMO made the vehicle respond to a junction foe (libsumo junction foes) and the vehicle was
  slow or braking while the foe was inside the conflict area or at most `FOE_HORIZON_S` from it, and
  the foe entered the conflict area while the vehicle was still before it, first in line (a vehicle
  queued behind a leader that is still before the conflict area follows it; it does not yield).
  Equal-rank links (all-way stops) use first come: the foe must have stopped at the junction before the
  vehicle. Attributes: `junction`, `rule` (priority / first_come), `min_speed`, `stopped`, `ego_lane`,
  `foe_lane`, `roundabout`.
- `go_first`: a vehicle that had to yield to a junction foe by priority (not an all-way stop) entered the
  conflict area first while the foe was at most `FOE_HORIZON_S` from it; `other_id` the foe. Attributes:
  `junction`, `gap_s`, `foe_dist`, `entry_step`, `bold`, `ego_lane`, `foe_lane`, `roundabout`.
- `decision`: a driver's decision made after its departure (`langtraj.synth.intents`): `decision`
  (route_choice, lane_change, pull_over, stop, speed_change, ped_wait), `decision_step`, what was chosen and
  `executed`; it spans the decision and what it led to.
- `junction_pass`: a vehicle or cyclist on the internal lanes of one junction, entry to exit. Attributes:
  `junction`, `direction` (SUMO link direction: s, l, r, t, L, R), `control` (SUMO junction type),
  `legs` (roads meeting there; 2 at a mid-block crossing), `intersection` (roads from two or more places
  meet roads to two or more: not a merge, split or mid-block crossing), `roundabout` (on a roundabout).
- `yield_to_pedestrian`: a slow or braking vehicle whose path within `PED_LOOKAHEAD_M` runs over a
  crosswalk on which a pedestrian is walking. Attributes: `crosswalk`, `min_speed`, `stopped`.
- `ped_waiting`: a pedestrian standing on a walking area right before walking onto a crossing.
- `ped_crossing`: a pedestrian on a crossing. Both have attribute `crosswalk` (SUMO crossing edge id).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from matplotlib.path import Path as MplPath

from langtraj.runs import true_runs, value_runs
from langtraj.scenario.model import STEP_SECONDS, BehaviorEvent
from langtraj.scenario.types import AgentType
from langtraj.synth.intents import Decision, decision_events
from langtraj.synth.records import LaneChangeRecord, Track
from langtraj.synth.runner import LEADER_RANGE_M, FoeObservation, SimulationLog

MAX_MANOEUVRE_STEPS = 50
"""A lane-change event spans at most 5 s either side of the switch (SUMO may start a manoeuvre, pause it
for a long time and finish it much later)."""

MIN_FOLLOW_STEPS = 10
"""A leader must be followed for at least 1 s to make a `follow` event."""

HELD_SPEED = 2.0
"""m/s: below this a vehicle approaching a conflict counts as held back."""

BRAKING = -0.5
"""m/s^2: deceleration that counts as responding to a foe."""

STOPPED_SPEED = 0.3
"""m/s: at or below this a vehicle is standing."""

FOE_HORIZON_S = 4.0
"""A foe counts only while it is inside the conflict area or at most this many seconds from it."""

MERGE_GAP = 5
"""Observations of one pair at most this many steps apart belong to one event."""

MIN_EVENT_STEPS = 5
"""Yield events shorter than this (0.5 s) are dropped as noise."""

PED_LOOKAHEAD_M = 12.0
"""How far ahead of its front a vehicle's path is checked against crosswalks."""

LANE_CHANGE_REASONS = ("strategic", "cooperative", "speedGain", "keepRight")


@dataclass(frozen=True)
class NetContext:
    """What event extraction needs to know about the network.

    `junction_of_lane` maps junction-internal lane ids to junction ids; `crosswalks` maps SUMO crossing
    edge ids to their polygons [K, 2]; `walkingareas` holds walking-area edge ids; `signal_columns` maps
    a SUMO lane id to the columns of the recorded signal states of the links leaving it; `link_direction`
    maps a junction-internal lane to its connection's direction, `junction_control` a junction to its SUMO
    type and `junction_legs` to its number of roads; `intersections`, `roundabout_junctions` and
    `ending_lanes` (lanes that end where the road goes on) are id sets.
    """

    junction_of_lane: Mapping[str, str]
    crosswalks: Mapping[str, np.ndarray]
    walkingareas: frozenset[str]
    signal_columns: Mapping[str, tuple[int, ...]] = field(default_factory=dict)
    link_direction: Mapping[str, str] = field(default_factory=dict)
    junction_control: Mapping[str, str] = field(default_factory=dict)
    junction_legs: Mapping[str, int] = field(default_factory=dict)
    intersections: frozenset[str] = frozenset()
    roundabout_junctions: frozenset[str] = frozenset()
    ending_lanes: frozenset[str] = frozenset()


def _acceleration(track: Track) -> np.ndarray:
    return np.gradient(track.speed, STEP_SECONDS) if len(track.speed) > 1 else np.zeros_like(track.speed)


def _edge_of(lane: str) -> str:
    return lane.rsplit("_", 1)[0]


# ---------------------------------------------------------------- lane changes


def _primary_reason(reason: str) -> str:
    tokens = reason.split("|")
    return next((t for t in tokens if t in LANE_CHANGE_REASONS), tokens[0])


def lane_change_events(
    records: Sequence[LaneChangeRecord], tracks: Mapping[str, Track], ending_lanes: frozenset[str] = frozenset()
) -> list[BehaviorEvent]:
    """One event per lane switch in SUMO's lane-change output, spanning its whole manoeuvre."""
    by_vehicle: dict[str, list[LaneChangeRecord]] = defaultdict(list)
    for rec in records:
        by_vehicle[rec.sumo_id].append(rec)
    events = []
    for sumo_id, recs in by_vehicle.items():
        track = tracks.get(sumo_id)
        if track is None:
            continue
        recs.sort(key=lambda r: (r.step, ("changeStarted", "change", "changeEnded").index(r.tag)))
        previous_change = -1
        for i, rec in enumerate(recs):
            if rec.tag != "change" or rec.direction == 0:
                continue
            started = [r.step for r in recs[:i] if r.tag == "changeStarted" and r.step > previous_change]
            ended = [r.step for r in recs[i + 1 :] if r.tag == "changeEnded"]
            start = max(max(started) if started else rec.step, rec.step - MAX_MANOEUVRE_STEPS, track.start)
            end = min((ended[0] if ended else rec.step) + 1, rec.step + MAX_MANOEUVRE_STEPS + 1, track.stop)
            previous_change = rec.step
            after = track.local(min(rec.step + 1, track.stop - 1))
            events.append(
                BehaviorEvent(
                    "lane_change",
                    track.track_id,
                    start,
                    max(end, start + 1),
                    int(track.leader[after]),
                    {
                        "direction": "left" if rec.direction > 0 else "right",
                        "reason": _primary_reason(rec.reason),
                        "reason_detail": rec.reason,
                        "from_lane": rec.from_lane,
                        "to_lane": rec.to_lane,
                        "change_step": rec.step,
                        "from_lane_ends": rec.from_lane in ending_lanes,
                    },
                )
            )
    return events


# ---------------------------------------------------------------- following


def follow_events(tracks: Iterable[Track]) -> list[BehaviorEvent]:
    """Runs of at least `MIN_FOLLOW_STEPS` steps behind the same leader at most `LEADER_RANGE_M` ahead (SUMO
    may report leaders further away than the range it was asked for)."""
    events = []
    for track in tracks:
        leader = np.where(track.gap <= LEADER_RANGE_M, track.leader, -1)
        if not (leader >= 0).any():
            continue
        change = np.flatnonzero(np.diff(leader) != 0) + 1
        bounds = zip(
            np.concatenate([[0], change]).tolist(), np.concatenate([change, [len(leader)]]).tolist(), strict=True
        )
        for a, b in bounds:
            if leader[a] < 0 or b - a < MIN_FOLLOW_STEPS:
                continue
            gaps = track.gap[a:b].astype(np.float64)
            events.append(
                BehaviorEvent(
                    "follow",
                    track.track_id,
                    track.start + a,
                    track.start + b,
                    int(leader[a]),
                    {
                        "min_gap": round(float(gaps.min()), 2),
                        "mean_gap": round(float(gaps.mean()), 2),
                        "start_gap": round(float(gaps[0]), 2),
                        "end_gap": round(float(gaps[-1]), 2),
                    },
                )
            )
    return events


# ---------------------------------------------------------------- yielding at junctions


_GREEN = np.array([ord("G"), ord("g")], np.uint8)


class HeldSteps:
    """Per track, the steps at which it is held back: slower than `HELD_SPEED` or braking harder than
    `BRAKING`, and not in front of a signal that shows no green for any link of its lane (waiting at a
    red light is not yielding)."""

    def __init__(self, log: SimulationLog, ctx: NetContext):
        self._names = log.lane_names
        self._states = log.signal_states
        self._columns = ctx.signal_columns
        self._cache: dict[int, np.ndarray] = {}

    def _red(self, track: Track) -> np.ndarray:
        red = np.zeros(len(track.valid), bool)
        for lane in np.unique(track.lane[track.lane >= 0]):
            columns = self._columns.get(self._names[lane])
            if columns:
                at = np.flatnonzero(track.lane == lane)
                states = self._states[track.start + at][:, list(columns)]
                red[at] = ~np.isin(states, _GREEN).any(axis=1)
        return red

    def of(self, track: Track) -> np.ndarray:
        held = self._cache.get(track.track_id)
        if held is None:
            slow = (track.speed < HELD_SPEED) | (_acceleration(track) < BRAKING)
            held = self._cache[track.track_id] = slow & track.valid & ~self._red(track)
        return held


def _arrival_steps(observations: Sequence[FoeObservation], tracks: Mapping[str, Track], ctx: NetContext):
    """(vehicle, junction) -> first step the vehicle stood while it had a foe there (first-come order)."""
    arrival: dict[tuple[str, str], int] = {}
    for obs in observations:
        track = tracks[obs.ego]
        junction = ctx.junction_of_lane.get(obs.ego_lane, _edge_of(obs.ego_lane))
        key = (obs.ego, junction)
        if key not in arrival and track.speed[track.local(obs.step)] <= STOPPED_SPEED:
            arrival[key] = obs.step
    return arrival


def yield_events(
    observations: Sequence[FoeObservation], tracks: Mapping[str, Track], ctx: NetContext, held: HeldSteps
) -> list[BehaviorEvent]:
    """Vehicles held back for a junction foe that SUMO gave priority (first come at equal rank)."""
    pairs: dict[tuple[str, str], list[FoeObservation]] = defaultdict(list)
    for obs in observations:
        if obs.ego in tracks and obs.foe in tracks:
            pairs[(obs.ego, obs.foe)].append(obs)
    arrival = _arrival_steps(observations, tracks, ctx)
    events = []
    for (ego, foe), obs_list in sorted(pairs.items()):
        track, foe_track = tracks[ego], tracks[foe]
        junction = ctx.junction_of_lane.get(obs_list[0].ego_lane, _edge_of(obs_list[0].ego_lane))
        mutual = any(o.mutual for o in obs_list)
        if mutual:
            ego_arrival = arrival.get((ego, junction))
            foe_arrival = arrival.get((foe, junction))
            if foe_arrival is None or (ego_arrival is not None and foe_arrival >= ego_arrival):
                continue
        steps = np.array([o.step for o in obs_list])
        before = np.array([o.ego_dist > 0.0 for o in obs_list])
        foe_inside_first = np.array([o.foe_dist <= 0.0 < o.ego_dist for o in obs_list])
        if not foe_inside_first.any():
            continue
        local = steps - track.start
        foe_speed = np.maximum(foe_track.speed[steps - foe_track.start], 1.0)
        foe_dist = np.array([o.foe_dist for o in obs_list])
        near = foe_dist / foe_speed <= FOE_HORIZON_S
        ego_dist = np.array([o.ego_dist for o in obs_list])
        queued = (track.leader[local] >= 0) & (track.gap[local] < ego_dist)  # a leader still before the conflict
        keep = before & near & ~queued & held.of(track)[local]
        if not keep.any():
            continue
        mask = np.zeros(steps.max() - steps.min() + 1, bool)
        mask[steps[keep] - steps.min()] = True
        for a, b in true_runs(mask, max_gap=MERGE_GAP):
            start, end = int(steps.min() + a), int(steps.min() + b)
            if end - start < MIN_EVENT_STEPS:
                continue
            window = track.speed[track.local(start) : track.local(end)]
            events.append(
                BehaviorEvent(
                    "yield",
                    track.track_id,
                    start,
                    end,
                    foe_track.track_id,
                    {
                        "junction": junction,
                        "rule": "first_come" if mutual else "priority",
                        "min_speed": round(float(window.min()), 2),
                        "stopped": bool(window.min() <= STOPPED_SPEED),
                        "ego_lane": obs_list[0].ego_lane,
                        "foe_lane": obs_list[0].foe_lane,
                        "roundabout": junction in ctx.roundabout_junctions,
                    },
                )
            )
    return events


GO_FIRST_LEAD_STEPS = 20
"""A `go_first` event starts this many steps (2 s) before the vehicle enters the conflict area."""

GO_FIRST_TAIL_STEPS = 10
"""... and ends this many steps after it."""


def go_first_events(
    observations: Sequence[FoeObservation],
    tracks: Mapping[str, Track],
    ctx: NetContext,
    bold: frozenset[str] = frozenset(),
) -> list[BehaviorEvent]:
    """Vehicles that had to yield to a junction foe by priority but entered the conflict area first, while
    the foe was at most `FOE_HORIZON_S` from it (the gap they accepted). Attributes: `junction`, `gap_s`
    (the foe's time to the conflict area), `foe_dist`, `bold` (a driver drawn to accept gaps it should
    leave, `langtraj.synth.intents`), `ego_lane`, `foe_lane`, `roundabout`."""
    firsts: dict[tuple[str, str], FoeObservation] = {}
    for obs in observations:
        if obs.mutual or obs.ego not in tracks or obs.foe not in tracks:
            continue
        if obs.ego_dist <= 0.0 < obs.foe_dist and (obs.ego, obs.foe) not in firsts:
            firsts[(obs.ego, obs.foe)] = obs
    events = []
    for (ego, foe), obs in sorted(firsts.items()):
        track, foe_track = tracks[ego], tracks[foe]
        if not foe_track.start <= obs.step < foe_track.stop:
            continue
        foe_speed = max(float(foe_track.speed[foe_track.local(obs.step)]), 1.0)
        gap = obs.foe_dist / foe_speed
        if gap > FOE_HORIZON_S:
            continue
        junction = ctx.junction_of_lane.get(obs.ego_lane, _edge_of(obs.ego_lane))
        start = max(track.start, obs.step - GO_FIRST_LEAD_STEPS)
        end = min(track.stop, obs.step + GO_FIRST_TAIL_STEPS)
        events.append(
            BehaviorEvent(
                "go_first",
                track.track_id,
                start,
                max(end, start + 1),
                foe_track.track_id,
                {
                    "junction": junction,
                    "gap_s": round(gap, 2),
                    "foe_dist": round(float(obs.foe_dist), 2),
                    "entry_step": obs.step,
                    "bold": ego in bold,
                    "ego_lane": obs.ego_lane,
                    "foe_lane": obs.foe_lane,
                    "roundabout": junction in ctx.roundabout_junctions,
                },
            )
        )
    return events


# ---------------------------------------------------------------- junction passages


def junction_pass_events(tracks: Iterable[Track], log: SimulationLog, ctx: NetContext) -> list[BehaviorEvent]:
    """One event per passage of a vehicle or cyclist over the internal lanes of a junction."""
    names = np.array(list(log.lane_names) or [""], dtype=object)
    junction_of = np.array([ctx.junction_of_lane.get(n, "") for n in names], dtype=object)
    events = []
    for track in tracks:
        if track.agent_type == AgentType.PEDESTRIAN:
            continue
        lane = np.maximum(track.lane, 0)
        junction = np.where(track.lane >= 0, junction_of[lane], "")
        codes = np.unique(junction.astype(str), return_inverse=True)[1].reshape(-1)
        for a, b in true_runs(junction != ""):
            for _, c, d in value_runs(codes[a:b]):
                node = str(junction[a + c])
                first_lane = str(names[lane[a + c]])
                events.append(
                    BehaviorEvent(
                        "junction_pass",
                        track.track_id,
                        track.start + a + c,
                        track.start + a + d,
                        -1,
                        {
                            "junction": node,
                            "direction": ctx.link_direction.get(first_lane, ""),
                            "control": ctx.junction_control.get(node, ""),
                            "legs": ctx.junction_legs.get(node, 0),
                            "intersection": node in ctx.intersections,
                            "roundabout": node in ctx.roundabout_junctions,
                        },
                    )
                )
    return events


# ---------------------------------------------------------------- pedestrians


def _lane_edges(log: SimulationLog) -> np.ndarray:
    return np.array([_edge_of(name) for name in log.lane_names] or [""], dtype=object)


def pedestrian_events(tracks: Iterable[Track], log: SimulationLog, ctx: NetContext) -> list[BehaviorEvent]:
    """`ped_crossing` runs on crossings and `ped_waiting` runs of standing on a walking area just before."""
    edges = _lane_edges(log)
    events = []
    for track in tracks:
        if track.agent_type != AgentType.PEDESTRIAN:
            continue
        edge = np.where(track.lane >= 0, edges[np.maximum(track.lane, 0)], "")
        on_crossing = np.array([e in ctx.crosswalks for e in edge], bool)
        for a, b in true_runs(on_crossing):
            crossing = str(edge[a])
            events.append(
                BehaviorEvent(
                    "ped_crossing", track.track_id, track.start + a, track.start + b, -1, {"crosswalk": crossing}
                )
            )
            if a == 0 or edge[a - 1] not in ctx.walkingareas:
                continue
            standing = (track.speed[:a] <= STOPPED_SPEED) & (edge[:a] == edge[a - 1])
            wait = true_runs(standing)
            if wait and wait[-1][1] >= a - 2 and wait[-1][1] - wait[-1][0] >= MIN_EVENT_STEPS:
                w0, w1 = wait[-1]
                events.append(
                    BehaviorEvent(
                        "ped_waiting", track.track_id, track.start + w0, track.start + w1, -1, {"crosswalk": crossing}
                    )
                )
    return events


def _crossing_occupancy(events: Sequence[BehaviorEvent]) -> dict[str, dict[int, list[int]]]:
    """crossing edge -> global step -> track ids of pedestrians on it."""
    occupancy: dict[str, dict[int, list[int]]] = defaultdict(lambda: defaultdict(list))
    for event in events:
        if event.kind == "ped_crossing":
            for step in range(event.start, event.end):
                occupancy[event.attributes["crosswalk"]][step].append(event.track_id)
    return occupancy


def _probe_hits(track: Track, local: np.ndarray, path: MplPath) -> np.ndarray:
    """Which of the `local` steps have the vehicle's look-ahead path over the polygon."""
    ahead = 0.5 * track.size[0] + np.linspace(0.5, PED_LOOKAHEAD_M, 24)
    direction = np.stack([np.cos(track.heading[local]), np.sin(track.heading[local])], axis=-1)
    probes = track.xy[local][:, None, :] + ahead[None, :, None] * direction[:, None, :]
    return path.contains_points(probes.reshape(-1, 2)).reshape(len(local), -1).any(axis=1)


def _nearest_pedestrian(track: Track, step: int, ped_ids: Sequence[int], tracks: Mapping[int, Track]) -> int:
    here = track.xy[track.local(step)]
    return min(ped_ids, key=lambda p: float(np.hypot(*(tracks[p].xy[tracks[p].local(step)] - here))))


def pedestrian_yield_events(
    tracks: Sequence[Track], ped_events: Sequence[BehaviorEvent], ctx: NetContext, held: HeldSteps
) -> list[BehaviorEvent]:
    """Vehicles held back before a crosswalk while a pedestrian walks on it."""
    occupancy = _crossing_occupancy(ped_events)
    by_id = {t.track_id: t for t in tracks}
    events = []
    for crossing, occupied in sorted(occupancy.items()):
        polygon = ctx.crosswalks[crossing]
        centre = polygon.mean(axis=0)
        reach = float(np.max(np.linalg.norm(polygon - centre, axis=1))) + PED_LOOKAHEAD_M + 6.0
        path = MplPath(polygon)
        occupied_steps = np.array(sorted(occupied))
        for track in tracks:
            if track.agent_type == AgentType.PEDESTRIAN:
                continue
            steps = occupied_steps[(occupied_steps >= track.start) & (occupied_steps < track.stop)]
            local = steps - track.start
            near = np.linalg.norm(track.xy[local] - centre, axis=1) < reach
            local = local[near & held.of(track)[local]]
            if local.size == 0:
                continue
            local = local[_probe_hits(track, local, path)]
            hits: dict[int, list[int]] = defaultdict(list)
            for i in local.tolist():
                step = track.start + i
                hits[_nearest_pedestrian(track, step, occupied[step], by_id)].append(step)
            events.extend(_pedestrian_yields(track, crossing, hits))
    return events


def _pedestrian_yields(track: Track, crossing: str, hits: Mapping[int, list[int]]) -> list[BehaviorEvent]:
    events = []
    for ped_id, steps in sorted(hits.items()):
        first = min(steps)
        mask = np.zeros(max(steps) - first + 1, bool)
        mask[np.array(steps) - first] = True
        for a, b in true_runs(mask, max_gap=MERGE_GAP):
            if b - a < MIN_EVENT_STEPS:
                continue
            speed = track.speed[track.local(first + a) : track.local(first + b)]
            attributes = {
                "crosswalk": crossing,
                "min_speed": round(float(speed.min()), 2),
                "stopped": bool(speed.min() <= STOPPED_SPEED),
            }
            events.append(
                BehaviorEvent("yield_to_pedestrian", track.track_id, first + a, first + b, ped_id, attributes)
            )
    return events


def extract_events(log: SimulationLog, tracks: Sequence[Track], ctx: NetContext) -> tuple[BehaviorEvent, ...]:
    """All events of a simulation, sorted by (start, track, kind, other)."""
    by_sumo = {t.sumo_id: t for t in tracks}
    bold = frozenset(d.sumo_id for d in log.decisions if d.decision == Decision.BOLD)
    peds = pedestrian_events(tracks, log, ctx)
    held = HeldSteps(log, ctx)
    events = [
        *lane_change_events(log.lane_changes, by_sumo, ctx.ending_lanes),
        *follow_events(tracks),
        *junction_pass_events(tracks, log, ctx),
        *yield_events(log.foe_observations, by_sumo, ctx, held),
        *go_first_events(log.foe_observations, by_sumo, ctx, bold),
        *decision_events(log.decisions, by_sumo, log.lane_names, log.lane_changes),
        *peds,
        *pedestrian_yield_events(tracks, peds, ctx, held),
    ]
    events.sort(key=lambda e: (e.start, e.track_id, e.kind, e.other_id, e.end))
    return tuple(events)
