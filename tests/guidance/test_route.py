"""Route costs (`guidance.route`) and the terms toward a prompted agent's target (`guidance.steering`): gradient
steps on the costs move a trajectory toward the target's path, past a goal station or back before a stop."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from langtraj.errors import InputError
from langtraj.guidance import GuidanceTerm, NoCollisionCost, RouteCost, StationCost, TargetSpeedCost
from langtraj.guidance.route import LeadCost, RoutePath
from langtraj.guidance.steering import ClearOfOthersCost, Steering
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.behaviours.base import HOLD_WEIGHT
from langtraj.interdrive.behaviours.brake_hard import KEEP_LANE_WEIGHT
from langtraj.interdrive.behaviours.pull_out import PULL_OUT_REACH_WEIGHT
from langtraj.interdrive.behaviours.run_red_light import RED_LIGHT_ROUTE_WEIGHT
from langtraj.interdrive.targets import BehaviourTarget

from .helpers import cost_gradient, make_scene

PATH = [[0.0, 3.5], [100.0, 3.5]]  # a lane 3.5 m to the left of a car driving along y = 0


def _driving(steps: int = 40, speed: float = 1.0, y: float = 0.0) -> torch.Tensor:
    """States [1, 1, steps, 4]: x advancing `speed` m per step along y."""
    x = torch.arange(1, steps + 1, dtype=torch.float32) * speed
    return torch.stack([x, torch.full_like(x, y), torch.zeros_like(x), torch.full_like(x, 10 * speed)], -1)[None, None]


def _descend(cost, states: torch.Tensor, scene, rate: float, steps: int = 60) -> torch.Tensor:
    for _ in range(steps):
        _, grad = cost_gradient(cost, states, scene)
        states = states - rate * grad
    return states


def test_route_cost_pulls_a_trajectory_onto_the_path_only_inside_its_window():
    scene = make_scene(1)
    states = _driving()
    cost = RouteCost(0, PATH, start=20)
    value, grad = cost_gradient(cost, states, scene)
    assert value.item() == pytest.approx(3.0 * (2 * 3.5 - 3.0))  # beyond the 3 m cap: linear (Huber)
    assert (grad[0, 0, :20] == 0).all() and (grad[0, 0, 20:, 1] < 0).all()  # a step against it moves y up
    moved = _descend(cost, states, scene, rate=2.0)
    assert torch.allclose(moved[0, 0, 20:, 1], torch.tensor(3.5), atol=0.05)
    assert torch.equal(moved[0, 0, :20], states[0, 0, :20])


def test_station_cost_reaches_past_a_goal_or_holds_before_a_stop_point():
    scene = make_scene(1)
    states = _driving(steps=40, speed=1.0, y=3.5)  # along the path, x from 1 to 40
    reach = StationCost(0, PATH, 60.0, mode="reach", start=35)
    moved = _descend(reach, states, scene, rate=1.0)
    assert (moved[0, 0, 35:, 0] >= 59.0).all() and torch.equal(moved[0, 0, :35], states[0, 0, :35])
    hold = StationCost(0, PATH, 10.0, mode="hold")
    value, _ = cost_gradient(hold, states, scene)
    assert value.item() == pytest.approx(float(np.mean(np.maximum(np.arange(1, 41) - 10.0, 0) ** 2)))
    held = _descend(hold, states, scene, rate=2.0)
    assert (held[0, 0, :, 0] <= 10.1).all() and held[0, 0, -1, 0] < 11.0  # from 40 m past it


def test_route_costs_refuse_bad_paths_and_modes():
    with pytest.raises(InputError, match="route: path must be at least two finite"):
        RouteCost(0, [[0.0, 0.0]])
    with pytest.raises(InputError, match="station: mode must be"):
        StationCost(0, PATH, 5.0, mode="past")  # type: ignore[arg-type]


def _steering(behaviour: Behaviour, **fields) -> Steering:
    path = np.stack([np.linspace(0, 100, 101), np.full(101, 3.5)], -1)
    target = BehaviourTarget(1, behaviour, path, "test", current_speed=10.0, **fields)
    return Steering(target, slot=0, other_slot=1 if target.other_id is not None else None)


def test_steering_terms_are_timed_from_the_start_of_the_simulation():
    change = _steering(Behaviour.LANE_CHANGE_LEFT)
    term, clear = change.terms(elapsed=0, horizon=80)
    assert isinstance(term.cost, RouteCost) and (term.cost.start, term.cost.end) == (39, 80)  # from 4 s on
    assert isinstance(clear.cost, ClearOfOthersCost)  # every step toward a target keeps clear of the others
    later, _ = change.terms(elapsed=30, horizon=80)
    assert (later.cost.start, later.cost.end) == (9, 50)  # the same simulated steps, 3 s later
    stop = _steering(Behaviour.STOP, station_of_goal=20.0, speed=0.0)
    kinds = {type(t.cost) for t in stop.terms(elapsed=0, horizon=80)}
    assert kinds == {StationCost, TargetSpeedCost, RouteCost, ClearOfOthersCost}
    speed = next(t.cost for t in stop.terms(0, 80) if isinstance(t.cost, TargetSpeedCost))
    assert speed.speeds == (0.0,) and speed.start == 39  # even braking over 20 m from 10 m/s takes 4 s
    assert _steering(Behaviour.LANE_CHANGE_LEFT).terms(elapsed=80, horizon=80) == []  # nothing left to steer


def test_a_steering_targets_path_is_built_once_and_moved_to_a_device_once_for_every_replan():
    stop = _steering(Behaviour.STOP, station_of_goal=20.0, speed=0.0)
    first, later = stop.terms(elapsed=0, horizon=80), stop.terms(elapsed=30, horizon=80)
    routes = [t.cost for t in first + later if isinstance(t.cost, RouteCost | StationCost)]
    assert len(routes) == 4 and all(cost.route is stop.route for cost in routes)  # one path, new windows
    states = _driving(steps=80, speed=0.5, y=1.0)
    scene = make_scene(1)
    assert stop.route.like(states) is stop.route.like(states)  # copied to the states' device and dtype once
    for cost in routes:  # the same values as the cost on a path of its own
        fresh = copy.copy(cost)
        fresh.route = RoutePath(stop.target.path)
        assert torch.equal(cost(states, scene), fresh(states, scene))
        assert torch.equal(cost(states.double(), scene), fresh(states.double(), scene))


def test_keeping_clear_of_others_is_an_agents_total_overlap_whatever_the_scenes_size():
    values = []
    for count in (2, 6):
        scene = make_scene(count)
        states = torch.zeros(1, count, 5, 4)
        states[0, :, :, 0] = torch.arange(count, dtype=torch.float32)[:, None] * 50.0  # all far apart ...
        states[0, 1, :, 0] = 1.0  # ... but agent 1 drives through agent 0
        value, grad = cost_gradient(ClearOfOthersCost(0), states, scene)
        pair = NoCollisionCost(0, others=1)(states, scene) * 2**2  # that one pair's mean overlap
        assert value.item() == pytest.approx(pair.item()) and 0 < value.item() <= 1.0
        assert grad[0, 0].abs().sum() > 0  # a gradient step moves the steered agent away
        values.append(value.item())
    assert values[0] == pytest.approx(values[1])


def test_every_term_toward_a_target_is_weighted_in_the_common_range():
    for behaviour in Behaviour:
        pair = behaviour in (Behaviour.GO_FIRST, Behaviour.YIELD, Behaviour.FOLLOW)
        fields = {"other_id": 2, "other_eta": 3.0, "other_speed": 8.0} if pair else {}
        steering = _steering(behaviour, station_of_goal=30.0, speed=5.0, settled_s=4.0, **fields)
        terms = steering.terms(0, 80)
        # a braking lead's lane is held harder (`KEEP_LANE_WEIGHT`): the model, conditioned on a stop, moves aside
        bound = [
            KEEP_LANE_WEIGHT if isinstance(t.cost, RouteCost) and behaviour is Behaviour.BRAKE_HARD else 4.0
            for t in terms
        ]
        assert terms and all(
            isinstance(t, GuidanceTerm) and 0 < t.weight <= b for t, b in zip(terms, bound, strict=True)
        ), behaviour


def test_a_braking_lead_keeps_its_speed_then_stands_from_when_its_braking_brings_it_to_rest_in_its_lane():
    lead = _steering(Behaviour.BRAKE_HARD, station_of_goal=22.5, speed=0.0, other_id=2, settled_s=3.5, deceleration=4.0)
    terms = lead.terms(0, 80)
    speeds = sorted((t.cost.start, t.cost.end, t.cost.speeds) for t in terms if isinstance(t.cost, TargetSpeedCost))
    assert speeds == [(0, 10, (10.0,)), (34, 80, (0.0,))]  # its speed for the first second; at rest from 3.5 s
    (hold,) = [t.cost for t in terms if isinstance(t.cost, StationCost)]
    assert (hold.station, hold.mode) == (22.5, "hold")
    (lane,) = [t for t in terms if isinstance(t.cost, RouteCost)]
    assert (lane.cost.start, lane.cost.end) == (0, 80) and lane.weight > 1.0  # in its lane throughout, held hard


def test_a_tailgater_reaches_its_station_when_the_target_says_and_keeps_the_others_speed_after():
    tail = _steering(Behaviour.TAILGATE, station_of_goal=50.0, speed=10.0, other_id=2, other_speed=10.0, settled_s=3.0)
    stations = sorted(
        (t.cost.mode, t.cost.start, t.cost.end) for t in tail.terms(0, 80) if isinstance(t.cost, StationCost)
    )
    assert stations == [("hold", 0, 30), ("reach", 29, 35)]
    speed = next(t.cost for t in tail.terms(0, 80) if isinstance(t.cost, TargetSpeedCost))
    assert (speed.speeds, speed.start) == ((10.0,), 29)
    with pytest.raises(ValueError, match="must say when it is settled"):  # a timed kind's target gives its time
        _steering(Behaviour.TAILGATE, station_of_goal=50.0, speed=10.0, other_id=2).terms(0, 80)


def test_lead_cost_keeps_an_agent_ahead_of_another_along_the_path_wherever_the_other_drives():
    scene = make_scene(2)
    two = torch.cat([_driving(y=3.5), _driving(speed=1.2)], dim=1)  # 1 in the lane beside gains 0.2 m a step
    reach = LeadCost(0, 1, PATH, 5.0, mode="reach", start=30)
    value, grad = cost_gradient(reach, two, scene)
    assert float(value) > 0 and (grad[0, 0, 30:, 0] < 0).all()  # 0 lags 1: pushed forward along the path
    assert (grad[0, 0, :30] == 0).all() and (grad[0, 1] == 0).all()  # only in its window, and only 0 is steered
    moved = _descend(reach, two, scene, rate=2.0, steps=200)
    assert float(reach(moved, scene)) < 0.05  # 5 m ahead of where 1 drives
    hold = LeadCost(0, 1, PATH, -10.0, mode="hold")
    assert float(hold(two, scene)) > 0 and float(LeadCost(0, 1, PATH, 0.0, mode="hold")(two, scene)) == 0.0
    assert float(reach(two, make_scene(2, valid=[True, False]))) == 0.0  # the other is padding: nothing to keep to
    with pytest.raises(InputError, match="another agent"):
        LeadCost(0, 0, PATH, 5.0)


def test_an_overtake_keeps_its_gap_to_where_the_other_drives_once_it_can_see_it():
    fields = {"station_of_goal": 80.0, "speed": 14.0, "other_id": 2, "settled_s": 6.0, "lead_m": 14.5}
    terms = _steering(Behaviour.OVERTAKE_CUT_IN, **fields).terms(0, 80)
    leads = sorted((t.cost.mode, t.cost.lead, t.cost.start, t.cost.end) for t in terms if isinstance(t.cost, LeadCost))
    assert leads == [("hold", 16.5, 0, 80), ("reach", 14.5, 59, 80)]  # never far ahead; the gap from 6 s on
    speed = next(t.cost for t in terms if isinstance(t.cost, TargetSpeedCost))
    assert (speed.speeds, speed.start, speed.end) == ((14.0,), 9, 30)  # passing speed from 1 s to the change
    target = BehaviourTarget(1, Behaviour.OVERTAKE_CUT_IN, _steering(Behaviour.STOP).target.path, "t", **fields)
    alone = Steering(target, slot=0, other_slot=None)  # the other is not the model's: the station instead
    assert any(isinstance(t.cost, StationCost) for t in alone.terms(0, 80))
    assert not any(isinstance(t.cost, LeadCost) for t in alone.terms(0, 80))


def test_a_cut_in_keeps_its_gap_to_where_the_other_drives_and_to_a_station_where_it_cannot_see_it():
    fields = {"station_of_goal": 55.0, "speed": 12.0, "other_id": 2, "settled_s": 4.0, "lead_m": 14.5}
    terms = _steering(Behaviour.CUT_IN, **fields).terms(0, 80)
    leads = sorted((t.cost.mode, t.cost.lead, t.cost.start, t.cost.end) for t in terms if isinstance(t.cost, LeadCost))
    assert leads == [("hold", 16.5, 0, 80), ("reach", 14.5, 39, 80)]
    (lane,) = [t.cost for t in terms if isinstance(t.cost, RouteCost)]
    assert (lane.start, lane.end) == (19, 80)  # in the other's lane from 2 s on
    target = BehaviourTarget(1, Behaviour.CUT_IN, _steering(Behaviour.STOP).target.path, "t", **fields)
    stations = {
        t.cost.mode for t in Steering(target, slot=0, other_slot=None).terms(0, 80) if isinstance(t.cost, StationCost)
    }
    assert stations == {"reach", "hold"}


def test_a_red_light_runner_goes_first_through_the_crossing_at_its_speed_on_its_way():
    runner = _steering(
        Behaviour.RUN_RED_LIGHT, station_of_goal=20.0, speed=8.0, other_id=2, other_eta=5.0, other_speed=8.0
    )
    terms = runner.terms(0, 80)
    (reach,) = [t.cost for t in terms if isinstance(t.cost, StationCost)]
    assert (reach.station, reach.mode, reach.start) == (25.0, "reach", 39)  # 5 m past the crossing, a second early
    speed = next(t.cost for t in terms if isinstance(t.cost, TargetSpeedCost))
    assert (speed.speeds, speed.start, speed.end) == ((8.0,), 9, 40)  # at its speed through the light until then
    routes = [t.weight for t in terms if isinstance(t.cost, RouteCost)]
    assert routes == [RED_LIGHT_ROUTE_WEIGHT] and RED_LIGHT_ROUTE_WEIGHT > 1.0  # held to its way, by one term


def test_a_pull_out_waits_until_it_sets_off_then_reaches_the_meeting_point_ahead_of_the_other():
    fields = dict(station_of_goal=15.0, speed=8.0, other_id=2, other_eta=6.0, other_speed=8.0, settled_s=4.0)
    joining = _steering(Behaviour.PULL_OUT, starts_s=1.5, lead_m=6.5, **fields).terms(0, 80)
    stations = {(t.cost.mode, t.cost.station, t.cost.start, t.cost.end, t.weight) for t in joining
                if isinstance(t.cost, StationCost)}  # fmt: skip
    assert stations == {("hold", 0.5, 0, 15, HOLD_WEIGHT), ("reach", 20.0, 39, 80, PULL_OUT_REACH_WEIGHT)}
    speeds = sorted((t.cost.speeds, t.cost.start, t.cost.end) for t in joining if isinstance(t.cost, TargetSpeedCost))
    assert speeds == [((0.0,), 0, 15), ((8.0,), 24, 80)]  # standing until 1.5 s, at its speed from a second after
    (lead,) = [t.cost for t in joining if isinstance(t.cost, LeadCost)]
    assert (lead.lead, lead.mode, lead.start) == (6.5, "reach", 39)  # ahead of where the other drives, once there
    crossing = _steering(Behaviour.PULL_OUT, starts_s=0.0, **fields).terms(0, 80)
    assert not any(isinstance(t.cost, LeadCost) for t in crossing)  # it crosses the other's way: no lead along it
    assert not any(isinstance(t.cost, StationCost) and t.cost.mode == "hold" for t in crossing)  # it goes at once
