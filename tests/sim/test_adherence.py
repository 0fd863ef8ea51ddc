"""Adherence of candidates (`sim.adherence`): on constructed trajectories that do and do not follow a prompt, the
candidate judge that selection uses agrees with the judge that scores instruction following, also on the yields
built around the thresholds an earlier rule of selection's own did not share with the detector (crossing radius,
wait extension, the passing agent's length, joined held runs, red lights, queues), and on the safety-critical kinds
judged by their own subtype (an overtake and cut-in, a red light run)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from interdrive.test_counterfactual import two_lane_road, x_junction_yield
from interdrive.test_ground_truth import PED, VEH, crosswalk, straight
from interdrive.test_ground_truth import scene as track_scene
from interdrive.test_heuristics import TIME, scene

from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.counterfactual import make_alternative
from langtraj.metrics.instruction_following import judge_rollouts
from langtraj.roads import MapIndex
from langtraj.rollouts.container import Rollouts
from langtraj.scenario import AgentType, Scenario, TrafficLights
from langtraj.scenario.types import StateField, TrafficLightState
from langtraj.sim.adherence import Ask, CandidateJudge
from langtraj.sim.world import SimWorld


def _eastbound(speeds: np.ndarray, y: np.ndarray | float = 0.0) -> tuple[AgentType, np.ndarray, np.ndarray]:
    x = np.concatenate([[0.0], np.cumsum(speeds[:-1] * 0.1)])
    y = np.broadcast_to(np.asarray(y, np.float64), x.shape)
    return AgentType.VEHICLE, np.stack([x, y], 1), np.arctan2(np.gradient(y), np.gradient(x))


def _future(s: Scenario, row: int) -> np.ndarray:
    """The logged future of `row` as poses [T, 4] (x, y, heading, speed)."""
    c = s.current_index
    st = s.agents.states[row, c + 1 :].astype(np.float64)
    xy = s.agents.states[row, c:, :2].astype(np.float64)
    speed = np.linalg.norm(np.diff(xy, axis=0), axis=1) / 0.1
    return np.concatenate([st[:, :2], st[:, 3:4], speed[:, None]], 1)


def _verdicts(
    candidates: list[Scenario], ask: Ask, driven: list[int], subtype: str | None = None
) -> tuple[list[bool], list[bool]]:
    """(candidate judge, instruction-following judge) verdicts of each candidate scene: its logged future is the
    candidate of every driven row (and what the judge reads of every other row); the judge asks for the
    interaction `subtype` (the behaviour's own by default)."""
    base = candidates[0]
    world = SimWorld(base, np.array(driven), 1)
    plans = np.stack([np.stack([_future(c, row) for row in driven])[None] for c in candidates])  # [M, 1, A, T, 4]
    judge = CandidateJudge(world, [ask], MapIndex.build(base.road_map))
    selection = (~judge.misses([0], world.start, plans)[0, :, 0]).tolist()
    checker = AdherenceChecker.build(base)
    alternative = make_alternative(ask.behaviour, ask.track_id, frozenset(), ask.other_id, subtype)
    scoring = []
    for c in candidates:
        rows = list(range(c.num_agents))
        futures = np.stack([_future(c, r) for r in rows])
        rollouts = Rollouts(
            object_id=c.agents.ids[rows],
            x=futures[None, ..., 0].astype(np.float32),
            y=futures[None, ..., 1].astype(np.float32),
            z=np.zeros((1, len(rows), futures.shape[1]), np.float32),
            heading=futures[None, ..., 2].astype(np.float32),
            scenario_id=c.scenario_id,
        )
        (verdict,) = judge_rollouts(base, rollouts, [alternative], checker=checker)
        scoring.append(verdict.followed)
    return selection, scoring


def test_a_stop_and_a_drive_on_are_judged_alike_by_selection_and_scoring():
    stops = np.where(TIME < 2.0, 10.0, np.maximum(10.0 - 4.0 * (TIME - 2.0), 0.0))
    candidates = [
        scene(two_lane_road(), _eastbound(stops)),
        scene(two_lane_road(), _eastbound(np.full_like(TIME, 10.0))),
    ]
    selection, scoring = _verdicts(candidates, Ask(1, 0, 0, Behaviour.STOP), [0])
    assert selection == scoring == [True, False]


def test_a_left_lane_change_and_keeping_the_lane_are_judged_alike():
    blend = np.clip((TIME - 3.0) / 3.0, 0.0, 1.0)
    change = 3.5 * (1 - np.cos(np.pi * blend)) / 2
    speeds = np.full_like(TIME, 10.0)
    candidates = [scene(two_lane_road(), _eastbound(speeds, change)), scene(two_lane_road(), _eastbound(speeds))]
    selection, scoring = _verdicts(candidates, Ask(1, 0, 0, Behaviour.LANE_CHANGE_LEFT), [0])
    assert selection == scoring == [True, False]


def test_an_overtake_and_cut_in_and_passing_without_cutting_in_are_judged_alike():
    blend = np.clip((TIME - 4.5) / 3.0, 0.0, 1.0)
    change = 3.5 - 3.5 * (1 - np.cos(np.pi * blend)) / 2  # from the left lane into the right from 4.5 s
    fast, slow = np.full_like(TIME, 14.0), np.full_like(TIME, 10.0)
    kind, xy, heading = _eastbound(slow)
    other = (kind, xy + [10.0, 0.0], heading)  # 10 m ahead in the right lane: passed at 4 m/s more by about 2.5 s
    candidates = [
        scene(two_lane_road(), _eastbound(fast, change), other),
        scene(two_lane_road(), _eastbound(fast, 3.5), other),
    ]
    ask = Ask(1, 0, 0, Behaviour.OVERTAKE_CUT_IN, other_id=2, other_row=1, other_slot=1)
    selection, scoring = _verdicts(candidates, ask, [0, 1])
    assert selection == scoring == [True, False]


@pytest.mark.parametrize(
    ("behaviour", "expected"), [(Behaviour.YIELD, [True, False]), (Behaviour.GO_FIRST, [False, True])]
)
def test_waiting_for_a_crossing_car_and_going_before_it_are_judged_alike(behaviour, expected):
    waits = x_junction_yield()  # car 1 waits west of the crossing while car 2 crosses northbound
    # ... or car 1 crosses while car 2 waits south of the crossing
    held = np.where(np.arange(len(TIME)) < 50, 0.0, 5.0)
    goes = track_scene({1: (VEH, straight(-8, 0, 0, 6.0)), 2: (VEH, straight(0, -8, np.pi / 2, held))})
    ask = Ask(1, 0, 0, behaviour, other_id=2, other_row=1, other_slot=1)
    verdicts = [_verdicts([candidate], ask, [0, 1]) for candidate in (waits, goes)]  # histories differ: one each
    selection = [v[0][0] for v in verdicts]
    scoring = [v[1][0] for v in verdicts]
    assert selection == scoring == expected


def test_the_copies_of_a_prompted_agent_form_a_valid_scene_whatever_its_self_driving_car():
    from dataclasses import replace

    s = replace(scene(two_lane_road(), _eastbound(np.full_like(TIME, 10.0)), _eastbound(np.full_like(TIME, 5.0), 3.5)))
    s = replace(s, sdc_index=1)  # a WOMD scene names its self-driving car; the copies scene has other rows
    world = SimWorld(s, np.array([0, 1]), 1)
    plans = np.stack([np.stack([_future(s, 0), _future(s, 1)])[None]])
    judge = CandidateJudge(world, [Ask(1, 0, 0, Behaviour.STOP)], MapIndex.build(s.road_map))
    assert judge.misses([0], world.start, plans).tolist() == [[[True]]]


# ------------------------------------------------------------------ yields at the thresholds of the detector
# Each scene is judged both ways round, by selection (`CandidateJudge`, every agent driven, its candidate the logged
# future) and by the experiment's judge (`judge_rollouts` on the same rollout): the prompted agent yields to the
# other (car 1 to car 2 unless said), and the other goes first. `expected` is whether car 1 yields.

STEPS = np.arange(len(TIME))
WAIT = np.where(STEPS < 50, 0.0, 5.0)  # stands until 5 s, then drives on at 5 m/s
NORTHBOUND = straight(0, -40, np.pi / 2, 10.0)  # crosses x = 0 northbound, at the centre at step 40


JUNCTION = ("yielding/intersection", "passing/intersection_with_yielding")


def _both_ways(s: Scenario, waiting: int, passing: int, subtypes: tuple[str, str]) -> tuple[list[bool], list[bool]]:
    """(selection, scoring) of "@waiting yields to @passing" and "@passing goes first over @waiting", judged by the
    `subtypes` the detector writes for each side of the yield."""
    rows = list(range(s.num_agents))
    w, p = s.agents.index_of(waiting), s.agents.index_of(passing)
    yields = Ask(waiting, w, w, Behaviour.YIELD, other_id=passing, other_row=p, other_slot=p)
    first = Ask(passing, p, p, Behaviour.GO_FIRST, other_id=waiting, other_row=w, other_slot=w)
    verdicts = [_verdicts([s], ask, rows, sub) for ask, sub in zip((yields, first), subtypes, strict=True)]
    return [v[0][0] for v in verdicts], [v[1][0] for v in verdicts]


def _agree(s: Scenario, expected: bool, waiting: int = 1, passing: int = 2, subtypes=JUNCTION) -> None:
    selection, scoring = _both_ways(s, waiting, passing, subtypes)
    assert selection == scoring == [expected, expected]


@pytest.mark.parametrize(("offset", "expected"), [(1.3, True), (1.7, False)])
def test_a_foe_passing_between_the_detector_radius_and_the_old_one_is_judged_alike(offset, expected):
    # car 2 sets off northbound `offset` m north of car 1's way: its path comes that close to car 1's
    # (1.7 m: no conflict point at the detector's 1.5 m, one at the 2 m selection used to take)
    slow = straight(0, offset, np.pi / 2, 1.0)
    _agree(track_scene({1: (VEH, straight(-8, 0, 0, WAIT)), 2: (VEH, slow)}), expected)


def _stop_before(distance: float) -> Scenario:
    """Car 1 brakes evenly from 6 m/s at 2 m/s^2 to stand `distance` m before the crossing to the end."""
    v = np.where(TIME < 1.0, 6.0, np.maximum(6.0 - 2.0 * (TIME - 1.0), 0.0))
    return track_scene({1: (VEH, straight(-distance - 15.0, 0, 0, v)), 2: (VEH, NORTHBOUND)})


@pytest.mark.parametrize(("distance", "expected"), [(8.0, True), (12.0, True), (17.0, False)])
def test_a_car_standing_within_the_wait_extension_is_judged_alike(distance, expected):
    # it never reaches the crossing: its way is extended 15 m (the detector's `wait_extension`, 10 m before)
    _agree(_stop_before(distance), expected)


@pytest.mark.parametrize(("length", "expected"), [(4.5, False), (12.0, True)])
def test_a_long_foe_is_at_the_crossing_by_its_own_half_length(length, expected):
    # car 2 creeps north and comes within 1.5 m + half its length of the crossing at 6 s; a 4.5 m car never
    # does, and the 2.25 m selection used for every agent never came in time for a 12 m truck either
    v = np.where(TIME < 2.0, 5.0, np.maximum(5.0 - 2.5 * (TIME - 2.0), 0.0))
    s = track_scene({1: (VEH, straight(-20, 0, 0, v)), 2: (VEH, straight(0, -10.5, np.pi / 2, 0.5))})
    s.agents.states[1, :, StateField.LENGTH] = length
    _agree(s, expected)


@pytest.mark.parametrize(("gap", "expected"), [(4, True), (7, False)])
def test_held_runs_joined_by_merge_gap_and_not_are_judged_alike(gap, expected):
    # car 1 slows to 1 m/s twice for 3 steps, `gap` steps apart, while car 2 crosses: two held runs of 4 steps,
    # one yield where `merge_gap` (5) joins them, none where it does not (8 held steps in all either way)
    v = np.full(len(TIME), 3.0)
    v[30:33] = 1.0
    v[33 + gap : 36 + gap] = 1.0
    _agree(track_scene({1: (VEH, straight(-30, 0, 0, v)), 2: (VEH, NORTHBOUND)}), expected)


@pytest.mark.parametrize(("light", "expected"), [(TrafficLightState.STOP, False), (TrafficLightState.GO, True)])
def test_waiting_at_a_red_light_is_no_yield_for_either_judge(light, expected):
    s = track_scene({1: (VEH, straight(-8, 0, 0, WAIT)), 2: (VEH, NORTHBOUND)})
    stop_line = [[-4.0, 0.0, 0.0]]  # 1.75 m ahead of car 1's front
    lights = TrafficLights([900], np.full((len(TIME), 1), light, np.int8), np.ones((len(TIME), 1), bool), stop_line)
    _agree(replace(s, traffic_lights=lights), expected)


@pytest.mark.parametrize(("light", "expected"), [(TrafficLightState.STOP, True), (TrafficLightState.GO, False)])
def test_running_a_red_light_across_a_crossing_car_is_judged_alike(light, expected):
    runner = straight(-40, -1.75, 0, 10.0)  # past its stop line (x = -8) at about 3.2 s, at 10 m/s throughout
    crossing = straight(1.75, -40, np.pi / 2, 8.0)  # northbound across its way, there at about 4.8 s
    lights = TrafficLights(
        [900], np.full((len(TIME), 1), light, np.int8), np.ones((len(TIME), 1), bool), [[-8, -1.75, 0]]
    )
    s = replace(track_scene({1: (VEH, runner), 2: (VEH, crossing)}), traffic_lights=lights)
    ask = Ask(1, 0, 0, Behaviour.RUN_RED_LIGHT, other_id=2, other_row=1, other_slot=1)
    selection, scoring = _verdicts([s], ask, [0, 1])
    assert selection == scoring == [expected]


def test_a_car_queued_behind_its_leader_yields_to_no_one_for_either_judge():
    queue = {1: (VEH, straight(-8, 0, 0, WAIT)), 3: (VEH, straight(-16, 0, 0, WAIT)), 2: (VEH, NORTHBOUND)}
    s = track_scene(queue)
    _agree(s, True, waiting=1)
    _agree(s, False, waiting=3)  # car 1, its leader, stands between it and the crossing


TO_PEDESTRIAN = ("yielding/to_pedestrian", "passing/vru_crossing")  # a car waits, a pedestrian goes first
PEDESTRIAN_WAITS = ("yielding/pedestrian_to_vehicle", "passing/pedestrian")  # a pedestrian waits, a car goes first


def test_yields_between_a_car_and_a_pedestrian_are_judged_alike():
    cw = [crosswalk(900, 26, 30, -3.5, 3.5)]
    walks = track_scene({1: (VEH, straight(20, 0, 0, 0.0)), 5: (PED, straight(28, -5, np.pi / 2, 1.2))}, features=cw)
    # the car waits for the pedestrian on the crosswalk ahead, and the pedestrian does not wait for the car
    _agree(walks, True, waiting=1, passing=5, subtypes=TO_PEDESTRIAN)
    _agree(walks, False, waiting=5, passing=1, subtypes=PEDESTRIAN_WAITS)
    stand = straight(30, -4.5, np.pi / 2, np.where(STEPS < 50, 0.0, 1.2))
    cw = [crosswalk(900, 29, 33, -3.5, 3.5)]
    waits = track_scene({1: (VEH, straight(20, 0, 0, 3.0)), 5: (PED, stand)}, features=cw)
    # the pedestrian waits while the car drives over its crosswalk
    _agree(waits, True, waiting=5, passing=1, subtypes=PEDESTRIAN_WAITS)


def test_selection_reads_the_detector_settings_it_is_given():
    from langtraj.interdrive.detector import DetectorConfig

    s = _stop_before(12.0)
    world = SimWorld(s, np.array([0, 1]), 1)
    plans = np.stack([np.stack([_future(s, 0), _future(s, 1)])[None]])
    ask = Ask(1, 0, 0, Behaviour.YIELD, other_id=2, other_row=1, other_slot=1)
    index = MapIndex.build(s.road_map)
    assert not CandidateJudge(world, [ask], index).misses([0], world.start, plans).any()
    short = DetectorConfig(wait_extension=10.0)  # the way on no longer reaches the crossing
    assert CandidateJudge(world, [ask], index, detector=short).misses([0], world.start, plans).all()


def test_a_lane_change_then_a_stop_is_judged_on_both_by_selection():
    blend = np.clip((TIME - 3.0) / 3.0, 0.0, 1.0)
    change = 3.5 * (1 - np.cos(np.pi * blend)) / 2
    cruise = np.full_like(TIME, 10.0)
    stops = np.where(TIME < 4.0, 10.0, np.maximum(10.0 - 4.0 * (TIME - 4.0), 0.0))
    candidates = [
        scene(two_lane_road(), _eastbound(stops, change)),
        scene(two_lane_road(), _eastbound(cruise, change)),  # changes lanes, never stops
        scene(two_lane_road(), _eastbound(stops)),  # stops in its own lane
    ]
    ask = Ask(1, 0, 0, Behaviour.LANE_CHANGE_LEFT, then=Behaviour.STOP)
    selection, _ = _verdicts(candidates, ask, [0])
    assert selection == [True, False, False]
    plain, _ = _verdicts(candidates, Ask(1, 0, 0, Behaviour.LANE_CHANGE_LEFT), [0])
    assert plain == [True, True, False]
