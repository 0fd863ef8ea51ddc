"""The interaction detector's rules, one `InteractionRule` per interaction type, registered in `INTERACTION_RULES`,
and `detect_interactions`, which runs them all over one `SceneGeometry` (docs/interdrive.md, 'Interaction
labels').
"""

from __future__ import annotations

import abc
import math
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.detector.config import MOVERS, DetectorConfig
from langtraj.interdrive.detector.parts import Pair
from langtraj.interdrive.detector.scene import SceneGeometry
from langtraj.interdrive.ground_truth import filter_to_window, label_sort_key
from langtraj.interdrive.labels import AgentLabel, InteractionLabel, LabelSource
from langtraj.interdrive.taxonomy import SUBTYPES_BY_ID, InteractionType
from langtraj.registry import Registry
from langtraj.roads import LaneChange, MapIndex
from langtraj.runs import true_runs
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import AgentType


class InteractionRule(abc.ABC):
    """Detects the labels of one interaction type in a scene."""

    name: ClassVar[str]
    type: ClassVar[InteractionType]

    @abc.abstractmethod
    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        """The labels of this rule's type in `scene` (window filtering happens afterwards)."""


INTERACTION_RULES: Registry[InteractionRule] = Registry("interaction rule")
"""Every interaction rule, by name; `detect_interactions` runs them in registration order."""


def _label(scene: SceneGeometry, agent: int, other: int, subtype: str, start: int, end: int) -> InteractionLabel:
    other_id = int(scene.ids[other]) if other >= 0 else -1
    return InteractionLabel(
        int(scene.ids[agent]),
        other_id,
        SUBTYPES_BY_ID[subtype],
        LabelSource.DETECTOR,
        int(start),
        int(max(end, start + 1)),
    )


def _pair_labels(
    scene: SceneGeometry, pairs: Sequence[Pair], subtype: str, reverse: bool = False
) -> list[InteractionLabel]:
    """One label of `subtype` per pair, agent to other (other to agent with `reverse`), over the pair's steps."""
    return [
        _label(scene, *((p.other, p.agent) if reverse else (p.agent, p.other)), subtype, p.start, p.end) for p in pairs
    ]


@INTERACTION_RULES.register
class LaneChangeRule(InteractionRule):
    """A switch to a neighbour lane, with the leader on the target lane (or the overtaken agent); and, where a
    vehicle follows within `cut_in_range` in the target lane right after the switch, a cut-in in front of it."""

    name = "lane_change"
    type = InteractionType.LANE_CHANGE

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        changes = scene.changes
        labels = []
        for change in changes.lane_changes:
            if changes.is_merge(change):
                continue
            overtake = changes.overtakes.get(change)
            if overtake is not None:
                labels.append(
                    _label(scene, change.agent, overtake.other, "lane_change/for_overtaking", change.start, change.end)
                )
                continue
            other = changes.leader_after(change)
            labels.append(_label(scene, change.agent, other, self._subtype(scene, change), change.start, change.end))
        labels += [_label(scene, p.agent, p.other, "lane_change/cut_in", p.start, p.end) for p in _cut_ins(scene)]
        return labels

    @staticmethod
    def _subtype(scene: SceneGeometry, change: LaneChange) -> str:
        before = scene.changes.former_leader(change)
        if before >= 0 and scene.speed[before, change.switch] < scene.speed[change.agent, change.switch]:
            return "lane_change/avoiding_slower_traffic"
        heads = scene.heading[change.agent][scene.valid[change.agent]]
        if heads.size and np.abs(wrap_angle(heads - heads[0])).max() > math.radians(45.0):
            return "lane_change/for_turn_or_exit"
        return "lane_change/with_lead_or_trail"


@INTERACTION_RULES.register
class FollowingRule(InteractionRule):
    """At least 1 s behind the same leader on one's own path."""

    name = "following"
    type = InteractionType.FOLLOWING

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        return [_label(scene, p.agent, p.other, self.subtype(scene, p), p.start, p.end) for p in scene.paths.follows]

    @staticmethod
    def subtype(scene: SceneGeometry, pair: Pair) -> str:
        """The following subtype of one following run (stopping behind, tailgating, a slow lead, or plain)."""
        cfg = scene.config
        s = slice(pair.start, pair.end)
        speed = scene.speed[pair.agent, s]
        both = scene.valid[pair.agent, s] & scene.valid[pair.other, s]
        if (both & (speed <= cfg.stopped_speed)).any():
            return "following/stopping_behind_lead"
        speed = np.where(both, speed, 0.0)
        gap = np.linalg.norm(scene.xy[pair.agent, s] - scene.xy[pair.other, s], axis=1)
        gap -= 0.5 * (scene.length[pair.agent, s] + scene.length[pair.other, s])
        close = both & (speed >= cfg.tailgating_speed) & (gap < cfg.tailgating_headway_s * np.maximum(speed, 1e-3))
        if close.sum() >= cfg.min_follow_steps:
            return "following/tailgating"
        earlier = scene.speed[pair.agent, max(pair.start - 30, 0) : pair.start + 1]
        lead = scene.speed[pair.other, s][both].mean() if both.any() else 0.0
        if earlier.size and 0.5 <= lead <= cfg.slow_lead_ratio * earlier.max():
            return "following/slow_lead"
        return "following/with_lead"


@INTERACTION_RULES.register
class YieldingRule(InteractionRule):
    """Held before a crossing path's conflict point, or before a crosswalk in use; pedestrians waiting."""

    name = "yielding"
    type = InteractionType.YIELDING

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        roundabout = scene.lanes.has_roundabout
        junction = "yielding/roundabout" if roundabout else "yielding/intersection"
        changing = {c.agent for c in scene.changes.lane_changes}
        labels = []
        for p in scene.yields.vehicle_yields:
            sub = "yielding/to_merging_or_lane_change" if p.other in changing and not roundabout else junction
            labels.append(_label(scene, p.agent, p.other, sub, p.start, p.end))
        crossings = scene.crossings
        labels += _pair_labels(scene, crossings.pedestrian_yields, "yielding/to_pedestrian")
        labels += _pair_labels(scene, [w for w, _ in crossings.pedestrian_waits], "yielding/pedestrian_to_vehicle")
        return labels


@INTERACTION_RULES.register
class PassingRule(InteractionRule):
    """The other side of every yield: going first while another agent waits; a braking lead; a red light run across
    another's path."""

    name = "passing"
    type = InteractionType.PASSING

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        labels = []
        for p in scene.yields.vehicle_yields:
            if scene.lanes.has_roundabout:
                sub = "passing/roundabout"
            elif scene.types[p.other] == AgentType.CYCLIST:
                sub = "passing/vru_crossing"
            else:
                sub = "passing/intersection_with_yielding"
            labels.append(_label(scene, p.other, p.agent, sub, p.start, p.end))
        crossings = scene.crossings
        labels += _pair_labels(scene, crossings.pedestrian_yields, "passing/vru_crossing", reverse=True)
        labels += _pair_labels(scene, [v for _, v in crossings.pedestrian_waits], "passing/pedestrian")
        labels += _pair_labels(scene, _braking_leads(scene, scene.paths.follows), "passing/braking_lead")
        labels += _pair_labels(scene, _red_light_runs(scene), "passing/red_light_running")
        return labels


def _red_light_runs(scene: SceneGeometry) -> list[Pair]:
    """Every red light run across another road user's path (`RedLightGeometry.runs`), by each vehicle or cyclist
    that passes a red stop point, toward every other agent valid then."""
    red = scene.red_lights
    return [
        p
        for a in np.flatnonzero(scene.movers).tolist()
        if red.crossings(a).size
        for b in range(len(scene.ids))
        for p in red.runs(a, b)
    ]


def _braking_leads(scene: SceneGeometry, follows: Sequence[Pair]) -> list[Pair]:
    """Lead-to-follower pairs over the steps a lead brakes hard while followed: for each following run (follower,
    lead), the runs of steps from which the lead's speed, at least `hard_braking_speed`, drops by `hard_braking`
    m/s^2 or more on average over the next `hard_braking_steps`, both valid throughout (Euro NCAP's braking lead);
    each with the follower's `braking_response_s` after it (while it still follows), the time it has to brake in
    turn."""
    cfg, k = scene.config, scene.config.hard_braking_steps
    response = round(cfg.braking_response_s / STEP_SECONDS)
    out = []
    for p in follows:
        steps = np.arange(p.start, max(p.end - k, p.start))
        if steps.size == 0:
            continue
        v, both = scene.speed[p.other], scene.valid[p.other] & scene.valid[p.agent]
        drop = (v[steps] - v[steps + k]) / (k * STEP_SECONDS)
        hard = both[steps] & both[steps + k] & (v[steps] >= cfg.hard_braking_speed) & (drop >= cfg.hard_braking)
        out += [
            Pair(p.other, p.agent, int(steps[a]), min(int(steps[b - 1]) + k + 1 + response, p.end))
            for a, b in true_runs(hard)
        ]
    return out


@INTERACTION_RULES.register
class OvertakingRule(InteractionRule):
    """A lane change around a slower leader that ends with the changer ahead of it; and a cut-in by a vehicle that
    was behind the one it cuts in on shortly before (`_overtake_cut_ins`)."""

    name = "overtaking"
    type = InteractionType.OVERTAKING

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        labels = []
        for p in scene.changes.overtakes.values():
            top = scene.speed[p.agent, p.start : p.end][scene.valid[p.agent, p.start : p.end]]
            fast = top.size and top.max() >= scene.config.high_speed
            sub = "overtaking/high_speed" if fast else "overtaking/standard"
            labels.append(_label(scene, p.agent, p.other, sub, p.start, p.end))
        cut_ins = _overtake_cut_ins(scene)
        labels += [_label(scene, p.agent, p.other, "overtaking/cut_in", p.start, p.end) for p in cut_ins]
        return labels


@INTERACTION_RULES.register
class MergingRule(InteractionRule):
    """A lane change out of a lane that ends, with the leader on the target lane; and a vehicle pulling out in front
    of another from a side road, a driveway or the kerb (`PullOutGeometry`)."""

    name = "merging"
    type = InteractionType.MERGING

    def detect(self, scene: SceneGeometry) -> list[InteractionLabel]:
        changes = scene.changes
        labels = []
        for change in changes.lane_changes:
            if not changes.is_merge(change):
                continue
            a, s = change.agent, change.switch
            onramp = changes.from_other_road(change)
            before = scene.speed[a, max(s - 30, 0) : s][scene.valid[a, max(s - 30, 0) : s]]
            during = scene.speed[a, change.start : change.end][scene.valid[a, change.start : change.end]]
            if before.size and before.min() < scene.config.held_speed:
                sub = "merging/late"
            elif onramp and during.size > 1 and during[-1] - during[0] >= 2.0:
                sub = "merging/on_ramp_accelerating"
            else:
                sub = "merging/standard" if onramp else "merging/lane_reduction"
            labels.append(_label(scene, a, changes.leader_after(change), sub, change.start, change.end))
        return labels + _pair_labels(scene, _pull_outs(scene), "merging/pull_out")


def _pull_outs(scene: SceneGeometry) -> list[Pair]:
    """Every pull-out in front of another road user (`PullOutGeometry.runs`), by each vehicle or cyclist that is
    (nearly) standing at some step, toward every other mover."""
    found = scene.pull_outs
    return [
        p
        for a in np.flatnonzero(scene.movers).tolist()
        if found.could_pull_out(a)
        for b in np.flatnonzero(scene.movers).tolist()
        for p in found.runs(a, b)
    ]


def _window_steps(config: DetectorConfig) -> int:
    """Steps a label must overlap the current and future steps by (`min_window_s`)."""
    return round(config.min_window_s / STEP_SECONDS)


def detect_interactions(
    scenario: Scenario,
    agent_labels: Sequence[AgentLabel] = (),
    config: DetectorConfig | None = None,
    map_index: MapIndex | None = None,
) -> tuple[InteractionLabel, ...]:
    """Interaction labels of `scenario` from its trajectories and map by every registered rule (source DETECTOR);
    pass the scene's `map_index` to share the one the heuristic labeler used."""
    scene = SceneGeometry(scenario, agent_labels, config or DetectorConfig(), map_index)
    labels = [lab for cls in INTERACTION_RULES.classes() for lab in cls().detect(scene)]
    return tuple(sorted(filter_to_window(labels, scenario, _window_steps(scene.config)), key=label_sort_key))


# ---------------------------------------------------------------- one ordered pair


def _kept(scene: SceneGeometry, pairs: Sequence[Pair], subtype: str) -> list[Pair]:
    """The pairs whose labels `detect_interactions` keeps (`ground_truth.filter_to_window`); `subtype` only names
    the labels' type, which the filter does not read."""
    labels = _pair_labels(scene, pairs, subtype)
    kept = {id(lab) for lab in filter_to_window(labels, scene.scenario, _window_steps(scene.config))}
    return [p for p, lab in zip(pairs, labels, strict=True) if id(lab) in kept]


def _pair_yields(scene: SceneGeometry, agent: int, other: int) -> list[tuple[Pair, Pair]]:
    """(agent yields to other, other passes agent) for each yield of agent row `agent` to row `other` by the
    yield rule of their types, as `YieldingRule` and `PassingRule` write its two sides: between vehicles and
    cyclists `YieldGeometry.pair_yields`, a vehicle or cyclist to a pedestrian
    `CrosswalkGeometry.pedestrian_yield_runs`, a pedestrian waiting at a crosswalk for a vehicle or cyclist
    `CrosswalkGeometry.pedestrian_wait_runs` (the vehicle passes over its own steps on the crosswalk)."""
    movers, walking = scene.movers, scene.types == AgentType.PEDESTRIAN
    if movers[agent] and movers[other]:
        found = scene.yields.pair_yields(agent, other)
    elif movers[agent] and walking[other]:
        found = scene.crossings.pedestrian_yield_runs(agent, other)
    elif walking[agent] and movers[other]:
        return scene.crossings.pedestrian_wait_runs(agent, other)
    else:
        return []
    return [(p, Pair(p.other, p.agent, p.start, p.end)) for p in found]


def yielding_runs(scene: SceneGeometry, agent: int, other: int) -> list[Pair]:
    """The steps over which agent row `agent` yields to row `other`: the runs of the "yielding/..." labels of
    agent toward other that `detect_interactions` gives on `scene`'s scenario (any subtype), computed for the
    pair alone."""
    return _kept(scene, [y for y, _ in _pair_yields(scene, agent, other)], "yielding/intersection")


def passing_runs(scene: SceneGeometry, agent: int, other: int) -> list[Pair]:
    """The steps over which agent row `agent` goes first while row `other` yields to it: the runs of the
    "passing/..." labels of agent toward other that `detect_interactions` gives on `scene`'s scenario (any subtype
    but the braking lead's and the red-light run's, which have rules of their own: `braking_lead_runs`,
    `red_light_runs`), computed for the pair alone."""
    return _kept(scene, [p for _, p in _pair_yields(scene, other, agent)], "passing/intersection_with_yielding")


def _cut_in_changes(scene: SceneGeometry, agent: int | None = None) -> list[tuple[LaneChange, int]]:
    """The cut-ins of `scene` (`LaneChangeGeometry.cut_ins`; of row `agent` only, when given)."""
    return [(c, trail) for c, trail in scene.changes.cut_ins if agent is None or c.agent == agent]


def _cut_ins(scene: SceneGeometry, agent: int | None = None) -> list[Pair]:
    """The cut-ins of `scene` (`_cut_in_changes`) as pairs over their changes' steps."""
    return [Pair(c.agent, trail, c.start, c.end) for c, trail in _cut_in_changes(scene, agent)]


def _overtake_cut_ins(scene: SceneGeometry, agent: int | None = None) -> list[Pair]:
    """The cut-ins (`_cut_in_changes`) whose changer was not yet past the vehicle it cuts in on (its rear behind the
    other's front, along the other's heading: behind it or beside it) at a step within `overtake_cut_in_lookback`
    before the switch: it passed it first. Each runs from that step to the change's end."""
    out = []
    for change, trail in _cut_in_changes(scene, agent):
        a = change.agent
        lo = max(change.switch - scene.config.overtake_cut_in_lookback, 0)
        span = slice(lo, change.switch + 1)
        rel = scene.xy[a, span] - scene.xy[trail, span]
        head = scene.heading[trail, span]
        along = rel[:, 0] * np.cos(head) + rel[:, 1] * np.sin(head)
        lengths = 0.5 * (scene.length[a, span] + scene.length[trail, span])
        behind = np.flatnonzero(scene.valid[a, span] & scene.valid[trail, span] & (along < lengths))
        if behind.size:
            out.append(Pair(a, trail, lo + int(behind[0]), change.end))
    return out


def cut_in_runs(scene: SceneGeometry, agent: int, other: int) -> list[Pair]:
    """The steps over which agent row `agent` cuts in front of row `other`: the "lane_change/cut_in" labels of agent
    toward other that `detect_interactions` gives on `scene`'s scenario, computed for the pair alone."""
    return _kept(scene, [p for p in _cut_ins(scene, agent) if p.other == other], "lane_change/cut_in")


def overtake_cut_in_runs(scene: SceneGeometry, agent: int, other: int) -> list[Pair]:
    """The steps over which agent row `agent` overtakes row `other` and cuts in front of it: the
    "overtaking/cut_in" labels of agent toward other that `detect_interactions` gives on `scene`'s scenario, computed
    for the pair alone."""
    return _kept(scene, [p for p in _overtake_cut_ins(scene, agent) if p.other == other], "overtaking/cut_in")


def braking_lead_runs(scene: SceneGeometry, agent: int, other: int) -> list[Pair]:
    """The steps over which agent row `agent` brakes hard in front of row `other`, which follows it: the
    "passing/braking_lead" labels of agent toward other that `detect_interactions` gives on `scene`'s scenario,
    computed for the pair alone."""
    return _kept(scene, _braking_leads(scene, scene.paths.following(other, agent)), "passing/braking_lead")


def red_light_runs(scene: SceneGeometry, agent: int, other: int) -> list[Pair]:
    """The steps over which agent row `agent` runs a red light across row `other`'s path: its
    "passing/red_light_running" labels toward other that `detect_interactions` gives on `scene`'s scenario, computed
    for the pair alone."""
    return _kept(scene, scene.red_lights.runs(agent, other), "passing/red_light_running")


def pull_out_runs(scene: SceneGeometry, agent: int, other: int) -> list[Pair]:
    """The steps over which agent row `agent` pulls out in front of row `other`: its "merging/pull_out" labels toward
    other that `detect_interactions` gives on `scene`'s scenario, computed for the pair alone."""
    return _kept(scene, scene.pull_outs.runs(agent, other), "merging/pull_out")


def tailgating_runs(scene: SceneGeometry, agent: int, other: int) -> list[Pair]:
    """The steps over which agent row `agent` tailgates row `other`: its "following/tailgating" labels toward other
    that `detect_interactions` gives on `scene`'s scenario, computed for the pair alone."""
    runs = [p for p in scene.paths.following(agent, other) if FollowingRule.subtype(scene, p) == "following/tailgating"]
    return _kept(scene, runs, "following/tailgating")


def pair_rows(
    xy: np.ndarray, valid: np.ndarray, types: np.ndarray, agent: int, other: int, config: DetectorConfig
) -> np.ndarray:
    """The sorted agent rows whose tracks (`xy` [A, T, 2], `valid` [A, T], `types` [A]) the per-pair rules of rows
    `agent` and `other` read (`yielding_runs`, `passing_runs`, `following_runs`, either way round): the two, every
    vehicle or cyclist that comes within `leader_search` of either at a step both are valid (a leader of theirs),
    and, where one of the two is a pedestrian, every pedestrian (the nearest one on a crosswalk decides a yield to
    a pedestrian). On the scene cut to these rows the rules give the same runs."""
    rows = [np.array([agent, other])]
    movers = np.isin(types, MOVERS)
    for f in (agent, other):
        near = valid & valid[f][None, :] & (np.linalg.norm(xy - xy[f][None], axis=-1) < config.leader_search + 1.0)
        rows.append(np.flatnonzero(movers & near.any(axis=1)))
    if (types[[agent, other]] == AgentType.PEDESTRIAN).any():
        rows.append(np.flatnonzero(types == AgentType.PEDESTRIAN))
    return np.unique(np.concatenate(rows))


def following_runs(scene: SceneGeometry, agent: int, other: int) -> list[Pair]:
    """The steps over which agent row `agent` follows row `other` (`PathGeometry.following`): the runs of the
    "following/..." labels of agent toward other that `detect_interactions` gives on `scene`'s scenario (any
    subtype), computed for the pair alone."""
    return _kept(scene, scene.paths.following(agent, other), "following/with_lead")
