"""`sim.failures`: every off-road and collision event sorted by cause, on a constructed straight road (two lanes
east, road edges on both sides, tests/sim/test_parked.py) where each scene's rollouts are built so that their events
must fall under one cause; and the shares per cause sum to the offroad and collision rates of the same rollouts."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from langtraj.errors import InputError
from langtraj.metrics.controllability import collision_flags, collision_rate, offroad_flags, offroad_rate
from langtraj.rollouts import Rollouts
from langtraj.rollouts.baselines import generate_baseline
from langtraj.scenario import FUTURE_STEPS, AgentType, MapFeature, MapFeatureType
from langtraj.sim.failures import (
    BREAKDOWN_KEYS,
    CAUSES,
    COLLISION_CAUSES,
    OFFROAD_CAUSES,
    FailureScene,
    cause_breakdown,
    classify_failures,
    log_breakdown,
    log_rollouts,
)
from tests.sim.test_parked import KERB, PERSON, ROAD_END, C, road, road_scene, track

T = np.arange(1, FUTURE_STEPS + 1)  # future steps after the current one, in steps


def rollouts_of(scenario, paths: dict[int, tuple[np.ndarray, np.ndarray]], num_rollouts: int = 2) -> Rollouts:
    """The logged future of every agent, in each of `num_rollouts` rollouts, except the agents of `paths`, which
    follow their (x [80], y [80]) in rollout 0 (the other rollouts keep the log)."""
    future = scenario.agents.states[:, C + 1 :]
    fields = {n: np.repeat(future[None, :, :, k], num_rollouts, 0).copy() for k, n in enumerate(("x", "y", "z"))}
    fields["heading"] = np.repeat(future[None, :, :, 3], num_rollouts, 0).copy()
    for agent, (x, y) in paths.items():
        fields["x"][0, agent], fields["y"][0, agent] = x, y
    return Rollouts(object_id=scenario.agents.ids, scenario_id=scenario.scenario_id, **fields)


def drift_scene():
    """A car on the right lane drifting right across the road edge (0.05 m per step)."""
    scenario = road_scene([track((0.0, 0.0), (1.0, 0.0))])
    return scenario, rollouts_of(scenario, {0: (T * 1.0, -0.05 * T)})


def map_end_scene():
    """A car driving east past the end of the mapped road (x = 150), then bearing right off where the road was."""
    scenario = road_scene([track((120.0, 0.0), (1.0, 0.0))])
    x = 120.0 + T
    return scenario, rollouts_of(scenario, {0: (x, np.where(x < ROAD_END + 10, 0.0, -0.3 * (x - ROAD_END - 10)))})


def parked_scene():
    """A car parked at the kerb, moved by the simulation across the lanes into a car stopped on the left lane."""
    scenario = road_scene([track(KERB), track((36.0, 3.5))])
    return scenario, rollouts_of(scenario, {0: (KERB[0] + 0.1 * T, np.minimum(KERB[1] + 0.08 * T, 2.0))})


def overlap_scene():
    """Two cars on the right lane whose boxes already overlap at the current step of the log."""
    scenario = road_scene([track((60.0, 0.0), (1.0, 0.0)), track((63.0, 0.0), (1.0, 0.0))])
    return scenario, rollouts_of(scenario, {})


def pedestrian_scene():
    """Two pedestrians walking east side by side on the pavement (1.2 m apart), the second drawing nearer."""
    walk = (0.14, 0.0)
    scenario = road_scene(
        [track((40.0, 7.0), walk, PERSON), track((40.0, 8.2), walk, PERSON)], types=[AgentType.PEDESTRIAN] * 2
    )
    return scenario, rollouts_of(scenario, {1: (40.0 + 0.14 * T, 8.2 - 0.02 * T)})


def lane_change_scene():
    """A car on the right lane moving left into a car beside it on the left lane."""
    scenario = road_scene([track((80.0, 0.0), (1.0, 0.0)), track((84.0, 3.5), (1.0, 0.0))])
    return scenario, rollouts_of(scenario, {0: (80.0 + T, np.minimum(0.1 * T, 3.5))})


def rear_end_scene():
    """A car running into the one ahead of it on the same lane."""
    scenario = road_scene([track((20.0, 0.0), (1.0, 0.0)), track((40.0, 0.0), (0.5, 0.0))])
    return scenario, rollouts_of(scenario, {})


SCENES = {
    "drift": drift_scene,
    "map_ends": map_end_scene,
    "parked_moved": parked_scene,
    "log_overlap": overlap_scene,
    "pedestrian_group": pedestrian_scene,
    "lane_change": lane_change_scene,
    "other": rear_end_scene,
}


@pytest.mark.parametrize("cause", sorted(SCENES))
def test_each_constructed_event_is_sorted_into_its_cause(cause):
    scenario, rollouts = SCENES[cause]()
    report = classify_failures(scenario, rollouts)
    assert report.events, "the scene must fail"
    kinds = {"offroad"} if cause in ("drift", "map_ends") else {"collision"}
    assert {e.kind for e in report.events} == kinds
    assert {e.cause for e in report.events} == {cause}
    if kinds == {"collision"}:  # both agents of the pair, each touching the other
        assert sorted((e.agent_id, e.partner_id) for e in report.events if e.rollout == 0) == [(1, 2), (2, 1)]


def test_an_event_is_placed_at_its_first_step():
    scenario, rollouts = drift_scene()
    (event,) = classify_failures(scenario, rollouts).events
    # The car's right corners (1 m right of its centre) cross the edge at y = -1.75 once its centre is below -0.75.
    assert (event.rollout, event.agent_id, event.partner_id, event.step) == (0, 1, None, 15)
    assert event.xy == pytest.approx((16.0, -0.8))
    scenario, rollouts = lane_change_scene()
    steps = {e.step for e in classify_failures(scenario, rollouts).events}
    gaps = [
        np.hypot(rollouts.x[0, 0, t] - rollouts.x[0, 1, t], rollouts.y[0, 0, t] - rollouts.y[0, 1, t]) for t in steps
    ]
    assert len(steps) == 1 and max(gaps) < 5.0


def test_off_road_in_a_junction_or_on_an_island():
    scenario = road_scene([track((0.0, 0.0), (1.0, 0.0))], road_map=road(junction=True))
    _, rollouts = drift_scene()
    assert {e.cause for e in classify_failures(scenario, rollouts).events} == {"roundabout_or_junction"}
    # An island: a closed clockwise road-edge ring in a wide road; the car drives into it.
    ring = np.array([[40, 20, 0], [40, 30, 0], [50, 30, 0], [50, 20, 0], [40, 20, 0]], float)
    island = MapFeature(400, MapFeatureType.ROAD_EDGE_MEDIAN, ring)
    outer = MapFeature(
        401, MapFeatureType.ROAD_EDGE_BOUNDARY, [[0, 0, 0], [90, 0, 0], [90, 50, 0], [0, 50, 0], [0, 0, 0]]
    )
    scenario = road_scene(
        [track((20.0, 25.0), (1.0, 0.0))], road_map=road(edges=False, lanes=False, extra=(island, outer))
    )
    rollouts = rollouts_of(scenario, {0: (20.0 + T, np.full(FUTURE_STEPS, 25.0))})
    assert len(FailureScene.build(scenario).islands) == 1  # the ring, not the map's outline (counter-clockwise)
    events = classify_failures(scenario, rollouts).events  # both rollouts (the log drives on into it too)
    assert {(e.cause, e.step) for e in events} == {("roundabout_or_junction", 17)}  # its front reaches x = 40


def test_a_map_without_road_edges_is_not_measured():
    # Neither edges nor lanes (to derive edges from, where the metrics do): offroad cannot be measured.
    scenario, rollouts = drift_scene()
    scenario = road_scene([track((0.0, 0.0), (1.0, 0.0))], road_map=road(edges=False, lanes=False))
    report = classify_failures(scenario, rollouts)
    assert not [e for e in report.events if e.kind == "offroad"]
    assert (report.offroad_pairs, report.unmeasured_pairs) == (0, rollouts.num_rollouts)
    shares = report.shares()
    assert shares["offroad:no_road_edges"] == 1.0
    assert all(math.isnan(shares[f"offroad:{c}"]) for c in OFFROAD_CAUSES[1:])
    with pytest.raises(InputError, match="no road edges"):  # as the rate itself
        offroad_rate(scenario, rollouts)
    # A scene without vehicles has no pair to measure at all; one with road edges measures every vehicle pair.
    people, _ = pedestrian_scene()
    assert all(math.isnan(v) for k, v in cause_breakdown(people, rollouts_of(people, {})).items() if "offroad" in k)
    assert cause_breakdown(*drift_scene())["offroad:no_road_edges"] == 0.0


def noisy_scene():
    """Many events at once: the agents of the scenes above on one road, their log replayed with 1.5 m of noise over
    8 rollouts."""
    scenario = road_scene(
        [track((80.0, 0.0), (1.0, 0.0)), track((84.0, 3.5), (1.0, 0.0)), track(KERB), track((36.0, 3.5)),
         track((60.0, 0.0), (0.8, 0.0)), track((63.0, 0.0), (1.0, 0.0)), track((40.0, 7.0), (0.14, 0.0), PERSON)],
        types=[AgentType.VEHICLE] * 6 + [AgentType.PEDESTRIAN],
    )  # fmt: skip
    return scenario, generate_baseline("log_replay", scenario, 8, noise_std=1.5, seed=4)


@pytest.mark.parametrize("name", [*sorted(SCENES), "noisy"])
def test_the_shares_sum_to_the_offroad_and_collision_rates(name):
    scenario, rollouts = noisy_scene() if name == "noisy" else SCENES[name]()
    report = classify_failures(scenario, rollouts)
    shares = report.shares()
    assert set(shares) == set(BREAKDOWN_KEYS)
    if name != "pedestrian_group":  # no vehicle, no offroad rate
        _, offroad = offroad_flags(scenario, rollouts)
        assert sum(report.counts("offroad").values()) == offroad.sum()
        total = sum(shares[f"offroad:{c}"] for c in OFFROAD_CAUSES[1:])
        assert total == pytest.approx(offroad_rate(scenario, rollouts), abs=1e-12)
    assert sum(report.counts("collision").values()) == collision_flags(scenario, rollouts).sum()
    total = sum(shares[f"collision:{c}"] for c in COLLISION_CAUSES)
    assert total == pytest.approx(collision_rate(scenario, rollouts), abs=1e-12)
    assert {e.cause for e in report.events} <= set(CAUSES)
    if name == "noisy":
        assert len(report.events) > 10 and len({e.cause for e in report.events}) > 2


def test_the_causes_do_not_read_the_logged_future():
    scenario, rollouts = parked_scene()
    states = scenario.agents.states.copy()
    states[:, C + 1 :, :2] += 25.0  # the log's future somewhere else entirely
    moved = replace(scenario, agents=replace(scenario.agents, states=states))
    assert classify_failures(moved, rollouts) == classify_failures(scenario, rollouts)


def test_the_log_floor_reads_the_future():
    scenario, _ = overlap_scene()
    assert log_rollouts(scenario).reads_future_log
    floor = log_breakdown(scenario)
    assert floor["collision:log_overlap"] == 1.0 and floor["offroad:drift"] == 0.0
    scene = FailureScene.build(scenario)
    assert log_breakdown(scenario, scene=scene) == floor
    other = road_scene([track((60.0, 0.0)), track((70.0, 0.0))], scenario_id="another")
    with pytest.raises(InputError, match="failure scene"):
        log_breakdown(other, scene=scene)
