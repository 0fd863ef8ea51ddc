"""Ground-truth interaction labels of a synthesized window, mapped from its SUMO events (docs/data.md "Events").

The mapping is exact and deterministic: the same scenario always gives the same labels, in one order. Every
label is an ordered pair `track_id -> other_id` (`other_id` -1 when the event names no second agent) over
window steps [start, end). Thresholds live in `GroundTruthConfig`.

Mapping (checked top to bottom per event; A the event's agent, "lead" its `other_id`):

- `lane_change` with `from_lane_ends` (a forced merge), A -> lead:
  waited before the switch (below `waiting_speed` within `late_lookback_s`) -> `merging/late`;
  else in an `onramp` window, gaining >= `accelerating_gain` over the manoeuvre -> `merging/on_ramp_accelerating`;
  else onramp -> `merging/standard`; else -> `merging/lane_reduction`.
- `lane_change` `speedGain` around a slower former leader B (A's follow event ending within
  `overtake_leader_slack` of the switch) that A gets ahead of (along B's heading) later in the window:
  A -> B `lane_change/for_overtaking` over the change, and A -> B `overtaking/standard` (`overtaking/high_speed`
  when A's top speed >= `high_speed`) from the change to when A is ahead (or to the end of A's return change).
  The return change (opposite direction, later) gets no label of its own.
- other `lane_change`, A -> lead: `strategic` -> `lane_change/for_turn_or_exit`; `speedGain` ->
  `lane_change/avoiding_slower_traffic`; `cooperative`, `keepRight`, anything else -> `lane_change/with_lead_or_trail`.
- `follow`, A -> leader L: A stopped (<= `stopped_speed`) while L was in a `junction_pass` ->
  `following/stopping_behind_intersection`; A stopped -> `following/stopping_behind_lead`; time headway below
  `tailgating_headway_s` at >= `tailgating_speed` for `tailgating_min_steps` -> `following/tailgating`; L's mean
  speed in [`slow_lead_min_speed`, `slow_lead_ratio` x A's top speed over the `recent_s` before] ->
  `following/slow_lead`; else `following/with_lead`.
- `yield`, A -> foe F and the reverse F -> A: `roundabout` (absent: the window kind is `roundabout`) ->
  `yielding/roundabout` + `passing/roundabout`; F has a lane change overlapping the yield ->
  `yielding/to_merging_or_lane_change` + `passing/intersection_with_yielding`; F a cyclist ->
  `yielding/intersection` + `passing/vru_crossing`; else `yielding/intersection` + `passing/intersection_with_yielding`.
- `go_first` (A went before foe F it had to yield to), A -> F `passing/intersection_with_yielding`
  (`passing/roundabout` on a roundabout), and F -> A `yielding/intersection` (`yielding/roundabout`) when F
  lost at least `go_first_braking` over the event and `go_first_reaction_steps` after it.
- `decision` (a driver's own decision, `langtraj.synth.intents`): no interaction label; the single-agent
  labels judge what it led to.
- `yield_to_pedestrian`, A -> P `yielding/to_pedestrian` and P -> A `passing/vru_crossing`.
- `ped_waiting` of P: for each vehicle or cyclist V with its centre on the map CROSSWALK P steps onto (the one
  within `crosswalk_search` of P's first step after the wait, grown by `crosswalk_margin`) during the wait:
  P -> V `yielding/pedestrian_to_vehicle` over the wait and V -> P `passing/pedestrian` over V's steps on it.
- `ped_crossing`, `junction_pass`: context only, no label.

"lead" is the event's `other_id`: the leader on the target lane right after the switch (-1 when none).

Observability (what nobody could see in the window is not ground truth; each rule applies to both labelers where
it concerns the window, see `filter_to_window`):

- A label is kept when it overlaps the window's current and future steps [current_index, num_steps) by at least
  `min_window_s` (1 s, as the window builder's own test of an interaction), both agents (or the one agent, for
  other -1) are in the scene, and each is valid at some step of that overlap.
- A lane change (and the merge or overtake made of it) needs its switch (`change_step`) inside the window:
  SUMO's manoeuvre may start up to 5 s before a switch that happens after the window's last step (or end after
  one before its first), and then no lane boundary is crossed in the scene.
- A follow keeps only the steps at which the leader's bumper gap (from positions) is at most `follow_range`
  (60 m: the range of the `follow` event as documented; SUMO also reports same-lane leaders farther ahead);
  runs shorter than 1 s are dropped.

Labels are sorted by (start, track, other, subtype, end).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from matplotlib.path import Path as MplPath

from langtraj.interdrive.labels import InteractionLabel, LabelSource
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID
from langtraj.scenario.model import STEP_SECONDS, BehaviorEvent, Scenario
from langtraj.scenario.types import AgentType, MapFeatureType


@dataclass(frozen=True)
class GroundTruthConfig:
    """Thresholds of the event -> label mapping (SI units; durations in seconds)."""

    stopped_speed: float = 0.3  # m/s: at or below this an agent stands (as the SUMO events)
    waiting_speed: float = 2.0  # m/s: a merger below this before its switch waited for a gap (late merge)
    late_lookback_s: float = 3.0  # how far before the switch waiting counts
    accelerating_gain: float = 2.0  # m/s gained over a merge to call it an accelerating on-ramp merge
    high_speed: float = 20.0  # m/s: an overtake at or above this top speed is high-speed
    overtake_leader_slack: int = 10  # steps: a follow event ending this close to a switch gives the former leader
    tailgating_headway_s: float = 0.6  # time headway (gap / speed) below which following is tailgating
    tailgating_speed: float = 5.0  # m/s: tailgating needs at least this speed
    tailgating_min_steps: int = 10  # steps the headway must stay short
    slow_lead_ratio: float = 0.6  # leader mean speed at most this share of the follower's recent top speed
    slow_lead_min_speed: float = 0.5  # m/s: a leader slower than this on average is stopped, not slow
    recent_s: float = 3.0  # how far back "recent" speed reaches before a follow event
    crosswalk_margin: float = 0.5  # m: a vehicle centre this close to a crosswalk polygon is on it
    crosswalk_search: float = 5.0  # m: the crosswalk of a waiting pedestrian is at most this far from its first step
    min_window_s: float = 1.0  # a label must overlap the current and future steps by this long
    follow_range: float = 60.0  # m: a follow counts while the leader's bumper gap is at most this
    min_follow_s: float = 1.0  # a follow (after the range cut) lasts at least this long
    go_first_braking: float = 1.0  # m/s a foe must lose after a vehicle went before it to count as yielding
    go_first_reaction_steps: int = 20  # how long after a go-first event the foe's braking is looked for


_SUB = SUBTYPES_BY_ID


@dataclass(frozen=True)
class _Context:
    """What the rules look up: the scene, its events by kind and the config."""

    scenario: Scenario
    config: GroundTruthConfig
    speed: np.ndarray  # [A, T]
    index: dict[int, int]
    by_kind: dict[str, tuple[BehaviorEvent, ...]]

    def events(self, kind: str, track_id: int | None = None) -> tuple[BehaviorEvent, ...]:
        found = self.by_kind.get(kind, ())
        return found if track_id is None else tuple(e for e in found if e.track_id == track_id)

    def speeds(self, track_id: int, start: int, end: int) -> np.ndarray:
        """Speeds of a track over valid steps in [start, end) (clipped to the window)."""
        a = self.index[track_id]
        start, end = max(start, 0), min(end, self.scenario.num_steps)
        valid = self.scenario.agents.valid[a, start:end]
        return self.speed[a, start:end][valid]


def _label(track: int, other: int, subtype: str, start: int, end: int) -> InteractionLabel:
    return InteractionLabel(track, other, _SUB[subtype], LabelSource.GROUND_TRUTH, int(start), int(max(end, start + 1)))


def ground_truth_interactions(
    scenario: Scenario, config: GroundTruthConfig | None = None
) -> tuple[InteractionLabel, ...]:
    """The interaction labels of `scenario` mapped from its SUMO events (see the module table)."""
    cfg = config or GroundTruthConfig()
    by_kind: dict[str, list[BehaviorEvent]] = {}
    for event in scenario.events:
        by_kind.setdefault(event.kind, []).append(event)
    ctx = _Context(
        scenario,
        cfg,
        scenario.agents.speed,
        {int(i): n for n, i in enumerate(scenario.agents.ids)},
        {k: tuple(v) for k, v in by_kind.items()},
    )
    labels = [
        *_lane_change_labels(ctx),
        *_follow_labels(ctx),
        *_yield_labels(ctx),
        *_go_first_labels(ctx),
        *_pedestrian_yield_labels(ctx),
        *_pedestrian_waiting_labels(ctx),
    ]
    min_steps = round(cfg.min_window_s / STEP_SECONDS)
    return tuple(sorted(filter_to_window(labels, scenario, min_steps), key=label_sort_key))


def label_sort_key(label: InteractionLabel) -> tuple:
    """The deterministic order of labels: (start, track, other, subtype id, end)."""
    return (label.start, label.track_id, label.other_id, label.subtype.id, label.end)


def filter_to_window(
    labels: Sequence[InteractionLabel], scenario: Scenario, min_steps: int = 1
) -> list[InteractionLabel]:
    """Labels overlapping [current_index, num_steps) by at least `min_steps` whose agents are in the scene
    (other -1 allowed) and valid, each, at some step of that overlap."""
    index = {int(i): n for n, i in enumerate(scenario.agents.ids)}
    valid = scenario.agents.valid
    out = []
    for lab in labels:
        lo, hi = max(lab.start, scenario.current_index), min(lab.end, scenario.num_steps)
        if hi - lo < max(min_steps, 1) or lab.track_id not in index:
            continue
        if not valid[index[lab.track_id], lo:hi].any():
            continue
        if lab.other_id != -1 and (lab.other_id not in index or not valid[index[lab.other_id], lo:hi].any()):
            continue
        out.append(lab)
    return out


# ---------------------------------------------------------------- lane changes, merges, overtakes


def _lane_change_labels(ctx: _Context) -> list[InteractionLabel]:
    labels: list[InteractionLabel] = []
    returns: set[tuple[int, int]] = set()
    changes = ctx.events("lane_change")
    for event in changes:
        if event.track_id not in ctx.index or not 0 <= _change_step(event) < ctx.scenario.num_steps:
            continue
        if event.attributes.get("from_lane_ends", False):
            labels.append(_merge_label(ctx, event))
            continue
        overtake = _overtake(ctx, event, changes) if event.attributes.get("reason") == "speedGain" else None
        if overtake is not None:
            labels.extend(overtake[0])
            if overtake[1] is not None:
                returns.add((overtake[1].track_id, overtake[1].start))
            continue
        labels.append(_label(event.track_id, event.other_id, _lane_change_subtype(event), event.start, event.end))
    return [
        lab
        for lab in labels
        if not (lab.type.value == "lane_change" and (lab.track_id, lab.start) in returns)
        or lab.subtype.key == "for_overtaking"
    ]


def _lane_change_subtype(event: BehaviorEvent) -> str:
    reason = event.attributes.get("reason", "")
    if reason == "strategic":
        return "lane_change/for_turn_or_exit"
    if reason == "speedGain":
        return "lane_change/avoiding_slower_traffic"
    return "lane_change/with_lead_or_trail"


def _change_step(event: BehaviorEvent) -> int:
    return int(event.attributes.get("change_step", event.start))


def _merge_label(ctx: _Context, event: BehaviorEvent) -> InteractionLabel:
    """A change out of an ending lane: late, on-ramp accelerating, standard or lane reduction."""
    cfg = ctx.config
    switch = _change_step(event)
    before = ctx.speeds(event.track_id, switch - round(cfg.late_lookback_s / STEP_SECONDS), switch)
    during = ctx.speeds(event.track_id, event.start, event.end)
    onramp = ctx.scenario.metadata.get("kind") == "onramp"
    if before.size and before.min() < cfg.waiting_speed:
        sub = "merging/late"
    elif onramp and during.size > 1 and during[-1] - during[0] >= cfg.accelerating_gain:
        sub = "merging/on_ramp_accelerating"
    else:
        sub = "merging/standard" if onramp else "merging/lane_reduction"
    return _label(event.track_id, event.other_id, sub, event.start, event.end)


def _former_leader(ctx: _Context, event: BehaviorEvent) -> int:
    """The leader A followed up to its switch (-1 when none)."""
    switch = _change_step(event)
    slack = ctx.config.overtake_leader_slack
    candidates = [
        f
        for f in ctx.events("follow", event.track_id)
        if f.start < switch and abs(f.end - switch) <= slack and f.other_id in ctx.index
    ]
    if not candidates:
        return -1
    return min(candidates, key=lambda f: (abs(f.end - switch), f.other_id)).other_id


def _ahead_step(ctx: _Context, track: int, other: int, start: int) -> int:
    """First step >= start at which `track` is ahead of `other` along `other`'s heading (-1 when never)."""
    agents = ctx.scenario.agents
    a, b = ctx.index[track], ctx.index[other]
    both = agents.valid[a, start:] & agents.valid[b, start:]
    rel = agents.xy[a, start:] - agents.xy[b, start:]
    head = agents.heading[b, start:]
    along = rel[:, 0] * np.cos(head) + rel[:, 1] * np.sin(head)
    hits = np.flatnonzero(both & (along > 0))
    return int(start + hits[0]) if hits.size else -1


def _overtake(
    ctx: _Context, event: BehaviorEvent, changes: Sequence[BehaviorEvent]
) -> tuple[list[InteractionLabel], BehaviorEvent | None] | None:
    """The lane-change and overtaking labels of a speed-gain change that passes its slower former leader,
    and the return change it absorbs; None when it is no overtake."""
    leader = _former_leader(ctx, event)
    if leader < 0:
        return None
    switch = _change_step(event)
    mine = ctx.speeds(event.track_id, event.start, switch + 1)
    theirs = ctx.speeds(leader, event.start, switch + 1)
    if not mine.size or not theirs.size or theirs.mean() >= mine.mean():
        return None
    ahead = _ahead_step(ctx, event.track_id, leader, event.start)
    if ahead < 0:
        return None
    back = next(
        (
            c
            for c in changes
            if c.track_id == event.track_id
            and c.start > event.start
            and c.attributes.get("direction") != event.attributes.get("direction")
        ),
        None,
    )
    end = max(ahead + 1, back.end if back is not None else 0, event.end)
    top = ctx.speeds(event.track_id, event.start, end)
    kind = "overtaking/high_speed" if top.size and top.max() >= ctx.config.high_speed else "overtaking/standard"
    labels = [
        _label(event.track_id, leader, "lane_change/for_overtaking", event.start, event.end),
        _label(event.track_id, leader, kind, event.start, end),
    ]
    return labels, back


# ---------------------------------------------------------------- following


def _follow_labels(ctx: _Context) -> list[InteractionLabel]:
    labels = []
    for event in ctx.events("follow"):
        if event.track_id not in ctx.index or event.other_id not in ctx.index:
            continue
        for start, end in _in_range(ctx, event):
            part = replace(event, start=start, end=end)
            labels.append(_label(event.track_id, event.other_id, _follow_subtype(ctx, part), start, end))
    return labels


def _gaps(ctx: _Context, track: int, other: int, start: int, end: int) -> np.ndarray:
    """Bumper gaps (centre distance less half of both lengths) over [start, end); NaN where either is invalid."""
    agents = ctx.scenario.agents
    a, b = ctx.index[track], ctx.index[other]
    s = slice(start, end)
    half = 0.5 * (agents.states[a, s, 6] + agents.states[b, s, 6])
    gap = np.linalg.norm(agents.xy[a, s] - agents.xy[b, s], axis=-1) - half
    return np.where(agents.valid[a, s] & agents.valid[b, s], gap, np.nan)


def _in_range(ctx: _Context, event: BehaviorEvent) -> list[tuple[int, int]]:
    """[start, end) runs of a follow event with the leader within `follow_range`, at least `min_follow_s` long
    (invalid steps inside the event are kept: SUMO saw the leader there)."""
    start, end = max(event.start, 0), min(event.end, ctx.scenario.num_steps)
    if end <= start:
        return []
    gap = _gaps(ctx, event.track_id, event.other_id, start, end)
    inside = ~(gap > ctx.config.follow_range)
    padded = np.concatenate([[False], inside, [False]])
    edges = np.flatnonzero(padded[1:] != padded[:-1])
    min_steps = round(ctx.config.min_follow_s / STEP_SECONDS)
    return [
        (start + int(a), start + int(b)) for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a >= min_steps
    ]


def _stopped_steps(ctx: _Context, track: int, start: int, end: int) -> np.ndarray:
    a = ctx.index[track]
    valid = ctx.scenario.agents.valid[a, start:end]
    return start + np.flatnonzero(valid & (ctx.speed[a, start:end] <= ctx.config.stopped_speed))


def _in_junction(ctx: _Context, track: int, steps: np.ndarray) -> bool:
    """Whether `track` passes a junction at one of `steps`."""
    return any(((steps >= e.start) & (steps < e.end)).any() for e in ctx.events("junction_pass", track))


def _tailgating(ctx: _Context, event: BehaviorEvent) -> bool:
    """Time headway below the threshold at speed for long enough."""
    cfg = ctx.config
    agents = ctx.scenario.agents
    a, b = ctx.index[event.track_id], ctx.index[event.other_id]
    s = slice(event.start, event.end)
    both = agents.valid[a, s] & agents.valid[b, s]
    half = 0.5 * (agents.states[a, s, 6] + agents.states[b, s, 6])
    gap = np.linalg.norm(agents.xy[a, s] - agents.xy[b, s], axis=-1) - half
    speed = ctx.speed[a, s]
    close = both & (speed >= cfg.tailgating_speed) & (gap < cfg.tailgating_headway_s * np.maximum(speed, 1e-3))
    return bool(_longest_run(close) >= cfg.tailgating_min_steps)


def _longest_run(mask: np.ndarray) -> int:
    if not mask.any():
        return 0
    padded = np.concatenate([[0], mask.astype(np.int8), [0]])
    edges = np.flatnonzero(np.diff(padded))
    return int((edges[1::2] - edges[::2]).max())


def _follow_subtype(ctx: _Context, event: BehaviorEvent) -> str:
    cfg = ctx.config
    stopped = _stopped_steps(ctx, event.track_id, event.start, event.end)
    if stopped.size:
        if _in_junction(ctx, event.other_id, stopped):
            return "following/stopping_behind_intersection"
        return "following/stopping_behind_lead"
    if _tailgating(ctx, event):
        return "following/tailgating"
    recent = ctx.speeds(event.track_id, event.start - round(cfg.recent_s / STEP_SECONDS), event.start + 1)
    lead = ctx.speeds(event.other_id, event.start, event.end)
    if recent.size and lead.size and cfg.slow_lead_min_speed <= lead.mean() <= cfg.slow_lead_ratio * recent.max():
        return "following/slow_lead"
    return "following/with_lead"


# ---------------------------------------------------------------- yielding and passing


def _changing_lanes(ctx: _Context, track: int, start: int, end: int) -> bool:
    return any(e.start < end and e.end > start for e in ctx.events("lane_change", track))


def _go_first_labels(ctx: _Context) -> list[InteractionLabel]:
    """A -> F passing for a vehicle that went before a foe it had to yield to; F -> A yielding when F then
    lost at least `go_first_braking` m/s."""
    labels = []
    roundabout_kind = ctx.scenario.metadata.get("kind") == "roundabout"
    for e in ctx.events("go_first"):
        if e.track_id not in ctx.index or e.other_id not in ctx.index:
            continue
        roundabout = e.attributes.get("roundabout", roundabout_kind)
        mine, theirs = (
            ("passing/roundabout", "yielding/roundabout")
            if roundabout
            else (
                "passing/intersection_with_yielding",
                "yielding/intersection",
            )
        )
        labels.append(_label(e.track_id, e.other_id, mine, e.start, e.end))
        foe = ctx.speeds(e.other_id, e.start, e.end + ctx.config.go_first_reaction_steps)
        if len(foe) and foe[0] - foe.min() >= ctx.config.go_first_braking:
            labels.append(_label(e.other_id, e.track_id, theirs, e.start, e.end))
    return labels


def _yield_labels(ctx: _Context) -> list[InteractionLabel]:
    labels = []
    roundabout_kind = ctx.scenario.metadata.get("kind") == "roundabout"
    types = ctx.scenario.agents.types
    for e in ctx.events("yield"):
        if e.track_id not in ctx.index or e.other_id not in ctx.index:
            continue
        if e.attributes.get("roundabout", roundabout_kind):
            mine, theirs = "yielding/roundabout", "passing/roundabout"
        elif _changing_lanes(ctx, e.other_id, e.start, e.end):
            mine, theirs = "yielding/to_merging_or_lane_change", "passing/intersection_with_yielding"
        elif types[ctx.index[e.other_id]] == AgentType.CYCLIST:
            mine, theirs = "yielding/intersection", "passing/vru_crossing"
        else:
            mine, theirs = "yielding/intersection", "passing/intersection_with_yielding"
        labels.append(_label(e.track_id, e.other_id, mine, e.start, e.end))
        labels.append(_label(e.other_id, e.track_id, theirs, e.start, e.end))
    return labels


def _pedestrian_yield_labels(ctx: _Context) -> list[InteractionLabel]:
    labels = []
    for e in ctx.events("yield_to_pedestrian"):
        if e.track_id in ctx.index and e.other_id in ctx.index:
            labels.append(_label(e.track_id, e.other_id, "yielding/to_pedestrian", e.start, e.end))
            labels.append(_label(e.other_id, e.track_id, "passing/vru_crossing", e.start, e.end))
    return labels


def _crosswalk_of(ctx: _Context, point: np.ndarray) -> MplPath | None:
    """The map crosswalk nearest to `point` within the search distance (None when none)."""
    best, best_dist = None, ctx.config.crosswalk_search
    for feature in ctx.scenario.road_map.of_type(MapFeatureType.CROSSWALK):
        polygon = feature.points[:, :2]
        if len(polygon) < 3:
            continue
        path = MplPath(polygon)
        dist = 0.0 if path.contains_point(point) else float(np.min(np.linalg.norm(polygon - point, axis=1)))
        if dist < best_dist:
            best, best_dist = path, dist
    return best


def _pedestrian_waiting_labels(ctx: _Context) -> list[InteractionLabel]:
    agents = ctx.scenario.agents
    movers = np.flatnonzero(np.isin(agents.types, [AgentType.VEHICLE, AgentType.CYCLIST]))
    labels = []
    for e in ctx.events("ped_waiting"):
        if e.track_id not in ctx.index:
            continue
        p = ctx.index[e.track_id]
        after = min(e.end, ctx.scenario.num_steps - 1)
        if not agents.valid[p, after]:
            continue
        crosswalk = _crosswalk_of(ctx, agents.xy[p, after].astype(np.float64))
        if crosswalk is None:
            continue
        for v in movers.tolist():
            steps = _steps_on(crosswalk, agents, v, e.start, e.end, ctx.config.crosswalk_margin)
            if steps.size:
                other = int(agents.ids[v])
                labels.append(_label(e.track_id, other, "yielding/pedestrian_to_vehicle", e.start, e.end))
                labels.append(_label(other, e.track_id, "passing/pedestrian", steps[0], steps[-1] + 1))
    return labels


def _steps_on(crosswalk: MplPath, agents, index: int, start: int, end: int, margin: float) -> np.ndarray:
    """Steps in [start, end) at which agent `index` has its centre on the crosswalk (grown by `margin`)."""
    valid = agents.valid[index, start:end]
    if not valid.any():
        return np.zeros(0, np.int64)
    inside = crosswalk.contains_points(agents.xy[index, start:end].astype(np.float64), radius=margin)
    # matplotlib's radius sign depends on the polygon's orientation; test both to grow it either way
    inside |= crosswalk.contains_points(agents.xy[index, start:end].astype(np.float64), radius=-margin)
    return start + np.flatnonzero(valid & inside)
