"""Controllability (minADE) and safety-critical metrics (pair collision, collision and offroad rates) on
constructed scenes with known answers, and on the real WOSAC reference rollouts."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from langtraj.errors import InputError
from langtraj.metrics.controllability import (
    ControllabilityResult,
    agent_rates,
    average_displacement,
    collision_events,
    collision_flags,
    collision_rate,
    controllability,
    min_ade,
    offroad_first_steps,
    offroad_flags,
    offroad_rate,
    pair_collision,
    pair_collision_rate,
    pair_distance,
    pooled_relative_reduction,
    safety,
)
from langtraj.metrics.interaction import distance_to_nearest_object, pair_signed_distance
from langtraj.rollouts import Rollouts, evaluated_agent_indices
from langtraj.scenario import FUTURE_STEPS, Agents, AgentType, MapFeature, MapFeatureType, RoadMap, Scenario, StateField

C = 10  # current step
STEPS = C + 1 + FUTURE_STEPS
WOMD_ID = "637f20cafde22ff8"
CAR = (4.5, 2.0, 1.6)


def track(start, step, heading: float = 0.0, size=CAR) -> np.ndarray:
    """States [91, 9] moving by `step` (x, y) per step from `start` (x, y), at z = 0.5."""
    out = np.zeros((STEPS, 9))
    out[:, :2] = np.asarray(start, float) + np.arange(STEPS)[:, None] * np.asarray(step, float)
    out[:, StateField.Z] = 0.5
    out[:, StateField.HEADING] = heading
    out[:, StateField.VX : StateField.VY + 1] = np.asarray(step, float) * 10
    out[:, StateField.LENGTH :] = size
    return out


def straight_edge(y: float, feature_id: int = 900, *, reverse: bool = False) -> MapFeature:
    """A road edge along +x at height 0, so the road is on its left (above the line); `reverse` runs it
    along -x, putting the road below it."""
    xs = np.linspace(-100, 200, 31)[:: -1 if reverse else 1]
    return MapFeature(feature_id, MapFeatureType.ROAD_EDGE_BOUNDARY, np.stack([xs, np.full(31, y), np.zeros(31)], 1))


def scene(tracks, types=None, valid=None, edges=(), scenario_id: str = "built") -> Scenario:
    """Agents 101, 102, ... following `tracks`; vehicles unless `types` says otherwise."""
    states = np.stack(tracks)
    num = len(tracks)
    return Scenario(
        scenario_id=scenario_id,
        timestamps=np.arange(STEPS) * 0.1,
        current_index=C,
        sdc_index=-1,
        agents=Agents(
            ids=np.arange(num) + 101,
            types=np.full(num, AgentType.VEHICLE, np.int8) if types is None else np.array(types, np.int8),
            states=states,
            valid=np.ones((num, STEPS), bool) if valid is None else valid,
        ),
        road_map=RoadMap(tuple(edges)),
    )


def log_rollouts(sc: Scenario, num_rollouts: int = 2) -> Rollouts:
    """`num_rollouts` copies of the logged future (writable arrays, to be edited per rollout)."""
    fut = sc.agents.states[:, C + 1 :]
    fields = {n: np.repeat(fut[None, :, :, k], num_rollouts, 0).copy() for n, k in zip("xyz", range(3), strict=True)}
    fields["heading"] = np.repeat(fut[None, :, :, StateField.HEADING], num_rollouts, 0).copy()
    return Rollouts(object_id=sc.agents.ids, scenario_id=sc.scenario_id, **fields)


def head_on() -> Scenario:
    """Car 101 drives east from x = 0 and car 102 west from x = 60 + 2 * 10 (at the current step both
    are 10 m along), 1 m per step each: gap = 60 - 2 (t + 1) - 4.5 at future step t, first < 0 at t = 27."""
    return scene([track((-10, 0), (1, 0)), track((70, 0), (-1, 0), heading=math.pi)])


# ------------------------------------------------------------------------------------ pair collisions


def test_head_on_cars_collide_in_every_rollout_at_the_right_step():
    sc = head_on()
    result = pair_collision(sc, log_rollouts(sc, 3), 101, 102)
    assert result.rate == 1.0
    assert result.collision_step == (27, 27, 27)
    assert pair_collision_rate(sc, log_rollouts(sc, 3), 102, 101) == 1.0
    dist = pair_distance(sc, log_rollouts(sc, 1), 101, 102)[0]
    np.testing.assert_allclose(dist[:26], 60 - 2 * (np.arange(26) + 1) - 4.5, atol=1e-4)


def test_parallel_lanes_five_metres_apart_never_collide():
    sc = scene([track((0, 0), (1, 0)), track((0, 5), (1, 0))])
    result = pair_collision(sc, log_rollouts(sc, 4), 101, 102)
    assert result.rate == 0.0
    assert result.collision_step == (-1, -1, -1, -1)
    # Side by side: 5 m between centres less two half widths = 3 m between the boxes.
    np.testing.assert_allclose(result.min_distance, 3.0, atol=1e-5)


def test_half_the_rollouts_colliding_gives_one_half():
    sc = head_on()
    ro = log_rollouts(sc, 4)
    ro.y[2:, 1] += 5.0  # the oncoming car keeps to a lane 5 m away in rollouts 2 and 3
    result = pair_collision(sc, ro, 101, 102)
    assert result.rate == 0.5
    assert result.collision_step == (27, 27, -1, -1)
    assert result.collided == (True, True, False, False)
    assert json.loads(json.dumps(result.to_dict()))["collision_step"] == [27, 27, -1, -1]


def test_boxes_touching_corner_to_corner_are_apart_once_rounded():
    """Sharp 4.5 x 2 boxes meeting at a corner touch; WOSAC's rounded ones are (1.4 sqrt 2 - 1.4) m apart."""
    d = pair_signed_distance(0.0, 0.0, 0.0, 4.5, 2.0, 4.5, 2.0, 0.0, 4.5, 2.0)
    assert d == pytest.approx(1.4 * math.sqrt(2) - 1.4)


def test_pair_distance_agrees_with_the_nearest_object_distance():
    rng = np.random.default_rng(3)
    x, y, h = rng.uniform(-5, 5, (3, 2, 40)), rng.uniform(-5, 5, (3, 2, 40)), rng.uniform(-3, 3, (3, 2, 40))
    length, width = np.full((3, 2, 40), 4.5), np.full((3, 2, 40), 2.0)
    nearest = distance_to_nearest_object(x, y, h, length, width, np.ones((3, 2, 40), bool), np.array([0]))[:, 0]
    pair = pair_signed_distance(x[:, 0], y[:, 0], h[:, 0], 4.5, 2.0, x[:, 1], y[:, 1], h[:, 1], 4.5, 2.0)
    np.testing.assert_allclose(pair, nearest, atol=1e-9)


def test_adversary_equal_to_target_is_an_error():
    sc = head_on()
    with pytest.raises(InputError, match="same object 101"):
        pair_collision_rate(sc, log_rollouts(sc), 101, 101)


def test_unknown_ids_are_named_with_the_valid_ones():
    sc = head_on()
    with pytest.raises(InputError, match=r"999 are not rollout agents \(valid ids: 101, 102\)"):
        pair_collision_rate(sc, log_rollouts(sc), 999, 102)
    big = scene([track((0, 10 * i), (1, 0)) for i in range(15)])
    with pytest.raises(InputError, match=r"7, 8 are not .*valid ids: 101, 102, .*\.\.\. \(15 in all\)") as err:
        min_ade(big, log_rollouts(big), [101, 7, 8])
    assert "115" not in str(err.value)
    with pytest.raises(InputError, match="repeated object ids 101"):
        min_ade(big, log_rollouts(big), [101, 101])


def test_rollouts_that_do_not_fit_the_scene_are_rejected():
    sc = head_on()
    other = scene([track((0, 0), (1, 0))])
    with pytest.raises(InputError, match="missing sim agents 102"):
        pair_collision_rate(sc, log_rollouts(other), 101, 102)


# ------------------------------------------------------------------------------------ collision rate


def test_collision_rate_over_rollout_agent_pairs():
    sc = scene([track((-10, 0), (1, 0)), track((70, 0), (-1, 0), heading=math.pi), track((0, 40), (1, 0))])
    ro = log_rollouts(sc, 2)
    ro.y[1, 1] += 5.0  # no collision in rollout 1
    flags = collision_flags(sc, ro)
    np.testing.assert_array_equal(flags, [[True, True, False], [False, False, False]])
    assert collision_rate(sc, ro) == pytest.approx(2 / 6)
    assert collision_rate(sc, ro, [101]) == 0.5
    assert collision_rate(sc, ro, [103]) == 0.0


def test_a_collision_event_names_the_deepest_contact():
    """Car 101 grazes 102 (nearest centre) and sits deep in 103 at the same first step: its partner is 103, the
    least signed distance; 102's first contact is 101 at that step."""
    sc = scene([track((0, 0), (1, 0)), track((-1, 1.9), (1, 0)), track((3.6, 0), (1, 0))])
    ro = log_rollouts(sc, 1)
    ro.x[0, 2, :20] += 20.0  # 103 far ahead until step 20, then 0.9 m of 101's front inside its rear
    ro.y[0, 1, :20] += 20.0  # 102 away until step 20, then beside 101 (0.1 m of width over)
    events = {(e.agent, e.other, e.step) for e in collision_events(sc, ro)}
    assert {(101, 103, 20), (102, 101, 20), (103, 101, 20)} <= events


# ------------------------------------------------------------------------------------ offroad


def test_offroad_with_a_straight_road_edge():
    """Edge along +x at y = -2 (road above it). Car 101 stays on the road; car 102 drifts below the edge
    in rollout 1 only; the pedestrian walks off the road but is not a vehicle."""
    tracks = [track((0, 0), (1, 0)), track((0, 3), (1, 0)), track((0, -5), (0.1, 0), size=(0.5, 0.5, 1.8))]
    sc = scene(tracks, types=[AgentType.VEHICLE, AgentType.VEHICLE, AgentType.PEDESTRIAN], edges=[straight_edge(-2)])
    ro = log_rollouts(sc, 2)
    ro.y[1, 1, 40:50] = -2.5  # box from -3.5 to -1.5: outside the edge by 1.5 m
    ids, flags = offroad_flags(sc, ro)
    np.testing.assert_array_equal(ids, [101, 102])
    np.testing.assert_array_equal(flags, [[False, False], [False, True]])
    _, first = offroad_first_steps(sc, ro)  # the first step off the road, -1: never
    np.testing.assert_array_equal(first, [[-1, -1], [-1, 40]])
    assert offroad_rate(sc, ro) == 0.25
    assert offroad_rate(sc, ro, [103]) == 1.0
    assert offroad_rate(sc, ro, [101, 102, 103]) == pytest.approx(3 / 6)


def test_edge_direction_decides_the_road_side():
    """The same edge reversed puts the road below it: now the car at y = 0 is off road."""
    sc = scene([track((0, 0), (1, 0))], edges=[straight_edge(-2, reverse=True)])
    assert offroad_rate(sc, log_rollouts(sc)) == 1.0


def test_offroad_without_road_edges_is_an_error():
    sc = head_on()
    with pytest.raises(InputError, match="no road edges, so offroad cannot be measured"):
        offroad_rate(sc, log_rollouts(sc))
    assert safety(sc, log_rollouts(sc), 101, 102).offroad_rate is None


def test_offroad_default_needs_a_vehicle():
    sc = scene([track((0, 0), (0.1, 0), size=(0.5, 0.5, 1.8))], types=[AgentType.PEDESTRIAN], edges=[straight_edge(-2)])
    with pytest.raises(InputError, match="no vehicle"):
        offroad_rate(sc, log_rollouts(sc))


def test_agent_rates_per_track_and_offroad_only_where_it_can_be_measured():
    tracks = [track((0, 0), (1, 0)), track((0, 3), (1, 0)), track((0, -5), (0.1, 0), size=(0.5, 0.5, 1.8))]
    sc = scene(tracks, types=[AgentType.VEHICLE, AgentType.VEHICLE, AgentType.PEDESTRIAN], edges=[straight_edge(-2)])
    ro = log_rollouts(sc, 2)
    ro.y[1, 1, 40:50] = -2.5
    collided, offroad = agent_rates(sc, ro)
    assert collided == dict(zip([101, 102, 103], collision_flags(sc, ro).mean(axis=0).tolist(), strict=True))
    assert offroad == {101: 0.0, 102: 0.5}  # vehicles only
    assert agent_rates(head_on(), log_rollouts(head_on()))[1] == {}  # no road edges: nothing to measure
    walker = scene([tracks[2]], types=[AgentType.PEDESTRIAN], edges=[straight_edge(-2)])
    assert agent_rates(walker, log_rollouts(walker)) == ({101: 0.0}, {})  # no vehicle: no offroad, no error


def test_safety_result_to_json():
    sc = scene(
        [track((-10, 0), (1, 0)), track((70, 0), (-1, 0), heading=math.pi)],
        edges=[straight_edge(-2), straight_edge(5, 901, reverse=True)],
    )
    result = safety(sc, log_rollouts(sc, 2), 101, 102)
    data = json.loads(json.dumps(result.to_dict()))
    assert data["pair_collision_rate"] == 1.0 == result.pair_collision_rate
    assert data["pair"]["collision_step"] == [27, 27]
    assert data["collision_rate"] == 1.0
    assert data["offroad_rate"] == 0.0  # both stay between the edges at y = -2 and y = 5
    assert data["num_rollouts"] == 2


# ------------------------------------------------------------------------------------ minADE


def two_cars() -> Scenario:
    return scene([track((0, 0), (1, 0)), track((0, 10), (1, 0))])


def test_min_ade_takes_the_best_rollout_per_agent():
    sc = two_cars()
    ro = log_rollouts(sc, 2)
    ro.y[0, 0] += 1.0  # agent 101: 1 m off in rollout 0, 3 m in rollout 1
    ro.y[1, 0] += 3.0
    ro.x[0, 1] += 3.0  # agent 102: 3 m off in rollout 0, 2 m in rollout 1
    ro.x[1, 1] -= 2.0
    ro.z[:] += 7.0  # height is not part of the displacement
    result = min_ade(sc, ro, [101, 102])
    np.testing.assert_allclose(result.per_agent, [1.0, 2.0], atol=1e-5)
    assert result.best_rollout == (0, 1)
    assert result.mean == pytest.approx(1.5, abs=1e-5)
    assert result.joint == pytest.approx(2.0, abs=1e-5)  # rollout 0: (1 + 3) / 2; rollout 1: (3 + 2) / 2
    assert min_ade(sc, ro, [101]).mean == pytest.approx(1.0, abs=1e-5)
    assert json.loads(json.dumps(result.to_dict()))["best_rollout"] == [0, 1]


def test_invalid_log_steps_are_left_out_of_the_average():
    tracks = [track((0, 0), (1, 0)), track((0, 10), (1, 0))]
    valid = np.ones((2, STEPS), bool)
    valid[0, C + 1 + 20 : C + 1 + 60] = False
    tracks[0][~valid[0], :3] = 1e4  # garbage where the log is invalid
    sc = scene(tracks, valid=valid)
    ro = log_rollouts(sc, 1)
    ro.x[0, 0] = track((0, 0), (1, 0))[C + 1 :, 0]  # the true path ...
    ro.y[0, 0, :] += 1.0  # ... 1 m off where the log is valid
    ro.y[0, 0, 20:60] += 99.0  # ... and 100 m off where it is not
    np.testing.assert_allclose(average_displacement(sc, ro, [101]), [[1.0]], atol=1e-5)


def test_agent_without_a_valid_logged_future_is_an_error():
    tracks = [track((0, 0), (1, 0)), track((0, 10), (1, 0))]
    valid = np.ones((2, STEPS), bool)
    valid[1, C + 1 :] = False
    sc = scene(tracks, valid=valid)
    with pytest.raises(InputError, match="agents 102 have no valid logged future step"):
        min_ade(sc, log_rollouts(sc), [101, 102])
    with pytest.raises(InputError, match="no agents"):
        min_ade(sc, log_rollouts(sc), [])


def test_controllability_relative_reduction():
    sc = two_cars()
    cond, uncond = log_rollouts(sc, 2), log_rollouts(sc, 3)
    cond.y[:, 0] += 1.0  # 101: 1 m conditioned, 2 m unconditioned -> reduction 0.5
    uncond.y[:, 0] += 2.0
    cond.y[:, 1] += 3.0  # 102: 3 m conditioned, 2 m unconditioned -> reduction -0.5
    uncond.y[:, 1] += 2.0
    result = controllability(sc, cond, uncond, [101, 102])
    assert isinstance(result, ControllabilityResult)
    assert result.min_ade_conditioned == pytest.approx(2.0, abs=1e-5)
    assert result.min_ade_unconditioned == pytest.approx(2.0, abs=1e-5)
    assert result.relative_reduction == pytest.approx(0.0, abs=1e-5)
    np.testing.assert_allclose(result.per_agent_relative_reduction, [0.5, -0.5], atol=1e-5)
    only_first = controllability(sc, cond, uncond, [101])
    assert only_first.relative_reduction == pytest.approx(0.5, abs=1e-5)
    # Pooled over scenes, each agent weighs the same: 1 - (1 + 3 + 1) / (2 + 2 + 2).
    assert pooled_relative_reduction([result, only_first]) == pytest.approx(1 - 5 / 6, abs=1e-5)
    data = json.loads(json.dumps(result.to_dict()))
    assert data["agent_ids"] == [101, 102]


def test_zero_unconditioned_min_ade_gives_no_reduction():
    sc = two_cars()
    result = controllability(sc, log_rollouts(sc), log_rollouts(sc), [101])
    assert result.min_ade_unconditioned == 0.0
    assert math.isnan(result.relative_reduction)
    assert result.to_dict()["relative_reduction"] is None


# ------------------------------------------------------------------------------------ real scene


@pytest.fixture(scope="module")
def reference(real_data_dir: Path):
    from langtraj.scenario.io import read_scenario

    folder = real_data_dir.parent / "wosac_reference"
    if not (folder / f"rollouts_{WOMD_ID}_log.npz").is_file():
        pytest.skip(f"WOSAC reference rollouts not found in {folder}")
    sc = read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord")
    official = json.loads((folder / "official_metrics.json").read_text())
    return sc, folder, official


def test_log_replay_has_zero_min_ade_on_the_real_scene(reference):
    sc, folder, _ = reference
    evaluated = [int(i) for i in sc.agents.ids[evaluated_agent_indices(sc)]]
    log = Rollouts.load(folder / f"rollouts_{WOMD_ID}_log.npz")
    result = min_ade(sc, log, evaluated)
    assert result.agent_ids == (1675, 1676, 2320, 2406)
    np.testing.assert_allclose(result.per_agent, 0.0, atol=1e-6)
    stationary = Rollouts.load(folder / f"rollouts_{WOMD_ID}_stationary.npz")
    assert controllability(sc, log, stationary, evaluated).relative_reduction == pytest.approx(1.0)


@pytest.mark.parametrize("policy", ["log", "const_vel"])
def test_evaluated_agent_rates_match_the_official_ones(reference, policy):
    """The official rates count only steps where the log is valid; on this scene that changes nothing."""
    sc, folder, official = reference
    evaluated = [int(i) for i in sc.agents.ids[evaluated_agent_indices(sc)]]
    ro = Rollouts.load(folder / f"rollouts_{WOMD_ID}_{policy}.npz")
    expected = official[f"rollouts_{WOMD_ID}_{policy}.npz"]["2025"]
    assert collision_rate(sc, ro, evaluated) == pytest.approx(expected["simulated_collision_rate"])
    assert offroad_rate(sc, ro, evaluated) == pytest.approx(expected["simulated_offroad_rate"])
