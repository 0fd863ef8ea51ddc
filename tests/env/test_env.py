"""The Gymnasium environment: its spaces pass Gymnasium's checker, episodes replay from their seed, actions move
the ego through the model's unicycle, bad actions fail with one line, and the simulated agents react to what the
ego does (docs/testing.md)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scenes import EGO_ID, FOLLOWER_ID, follower_scene

from langtraj.env import ENV_ID, LangTrajEnv
from langtraj.env.dynamics import step_unicycle
from langtraj.env.spaces import AgentColumn, EgoColumn, action_space, observation_space
from langtraj.errors import InputError

BRAKE = np.array([-4.0, 0.0], np.float32)


def run(env: LangTrajEnv, seed: int, action=BRAKE, steps: int = 80) -> list[dict]:
    env.reset(seed=seed)
    infos = []
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(action)
        assert observation_space().contains(obs)
        infos.append(info)
        if terminated or truncated:
            break
    return infos


@pytest.mark.parametrize("action", ["control", "trajectory"])
def test_gymnasium_checker_passes(action):
    with pytest.warns(UserWarning):  # the checker's note that a direct instance has no spec to re-make
        check_env(LangTrajEnv(follower_scene(), action=action, render_mode="rgb_array"), skip_render_check=False)


def test_registered_make_and_observation_contents():
    env = gymnasium.make(f"langtraj.env:{ENV_ID}", scenario=follower_scene())
    obs, info = env.reset(seed=0)
    assert info["ego_id"] == EGO_ID and info["route_source"] == "log" and info["logged_ego"].shape == (80, 4)
    assert obs["ego"][EgoColumn.SPEED] == pytest.approx(10.0, abs=0.05)  # its speed
    follower = list(obs["agents_id"]).index(FOLLOWER_ID)
    assert obs["agents"][follower, AgentColumn.X] == pytest.approx(-16.5, abs=0.1)  # 12 m gap + a car length, behind
    assert obs["route_valid"].all() and np.allclose(obs["route"][:, 1], 0.0, atol=1e-3)  # straight ahead
    assert not obs["route_speed_limit"].any()  # the constructed lanes give no speed limit
    assert obs["map_valid"].any() and action_space("control").contains(BRAKE)


def test_an_episode_replays_from_its_seed_and_differs_across_seeds():
    env = LangTrajEnv(follower_scene())
    first, again = run(env, 3, steps=25), run(env, 3, steps=25)
    assert first == again
    world_a = env.unwrapped._sim.world.states.copy()
    run(env, 4, steps=25)
    assert not np.array_equal(world_a, env.unwrapped._sim.world.states)


def test_the_follower_brakes_for_a_braking_ego_where_log_replay_runs_into_it():
    react = LangTrajEnv(follower_scene())
    clear = [not any(FOLLOWER_ID in i["collided_with"] for i in run(react, seed)) for seed in range(3)]
    assert sum(clear) >= 2, clear
    replay = LangTrajEnv(follower_scene(), policy="log_replay")
    infos = run(replay, 0)
    hit = next(i for i in infos if i["collision"])
    assert hit["collided_with"] == [FOLLOWER_ID] and not hit["at_fault"]  # rear-ended: not the ego's fault


def _braking(speed: float, accel: float, turn: float = 0.0) -> np.ndarray:
    """The 10 poses (ego frame) of the unicycle held at `accel` and yaw rate `turn` from `speed`."""
    pose, poses = np.array([0.0, 0.0, 0.0, speed]), []
    for _ in range(10):
        pose = step_unicycle(pose, np.array([accel, turn]))
        poses.append(pose[:3])
    return np.array(poses, np.float32)


def test_a_trajectory_action_is_tracked_over_its_horizon_and_a_bad_action_fails_in_one_line():
    env = LangTrajEnv(follower_scene(), action="trajectory")
    obs, _ = env.reset(seed=0)
    speed = float(obs["ego"][EgoColumn.SPEED])
    _, _, _, _, info = env.step(_braking(speed, -2.0))  # a profile the unicycle drives is followed exactly
    assert info["speed"] == pytest.approx(speed - 0.2, abs=1e-4)
    moved = {}
    for late, turn in ((-2.0, 0.0), (3.0, 0.4)):  # the same first pose, other later ones: the ego moves otherwise
        start, _ = env.reset(seed=0)
        path = _braking(speed, late, turn)
        path[0] = _braking(speed, -2.0)[0]
        obs, _, _, _, info = env.step(path)
        moved[late] = (info["speed"], float(obs["ego"][EgoColumn.HEADING] - start["ego"][EgoColumn.HEADING]))
    assert moved[3.0][0] > moved[-2.0][0] + 0.2 and moved[3.0][1] > moved[-2.0][1] + 0.02
    for bad, what in ((np.zeros(2), "shape"), (np.full((10, 3), np.nan), "non-finite")):
        env.reset(seed=0)
        with pytest.raises(InputError, match=f"action: .*{what}") as err:
            env.step(bad)
        assert "\n" not in str(err.value)


def test_bad_episodes_are_refused():
    with pytest.raises(InputError, match="lights: must be one of log, held, got 'frozen'"):
        LangTrajEnv(follower_scene(), lights="frozen")
    with pytest.raises(InputError, match="no agent @99"):
        LangTrajEnv(follower_scene(), ego=99).reset(seed=0)
    with pytest.raises(InputError, match="asks something of the ego"):
        LangTrajEnv(follower_scene(), prompts=["@ego slows down"]).reset(seed=0)
    with pytest.raises(InputError, match="options: unknown keys nope"):
        LangTrajEnv(follower_scene()).reset(seed=0, options={"nope": 1})


def test_a_collision_the_ego_causes_is_at_fault_and_terminates_on_request():
    env = LangTrajEnv(follower_scene(), ego=FOLLOWER_ID, policy="log_replay", terminate_on_collision=True)
    infos = run(env, 0, action=np.array([3.0, 0.0]))  # the new ego speeds into the car ahead
    assert infos[-1]["collision"] and infos[-1]["at_fault"] and infos[-1]["collided_with"] == [EGO_ID]
    assert len(infos) < 80


@pytest.mark.parametrize(
    ("mode", "options"),
    [("sync", {}), ("async", {"context": "spawn"})],  # async: each environment in a process of its own
)
def test_many_scenes_at_once_through_gymnasiums_vector_environment(mode, options):
    envs = gymnasium.make_vec(
        f"langtraj.env:{ENV_ID}", num_envs=2, vectorization_mode=mode, vector_kwargs=options, scenario=follower_scene()
    )
    obs, info = envs.reset(seed=[0, 1])
    assert obs["agents"].shape == (2, 16, 7) and list(info["ego_id"]) == [EGO_ID, EGO_ID]
    obs = envs.step(np.stack([BRAKE, np.zeros(2, np.float32)]))[0]
    speed = obs["ego"][:, EgoColumn.SPEED]
    assert speed[0] < speed[1]  # the first ego brakes, the second keeps its speed
    envs.close()


def test_a_window_of_a_longer_scene():
    from langtraj.scenario.windowing import cut_window, window_starts

    long = follower_scene(steps=200)
    env = LangTrajEnv(long, window=1)
    _, info = env.reset(seed=0)
    start = window_starts(long.num_steps)[1]
    assert info["logged_ego"][0, 0] == pytest.approx(float(cut_window(long, start).agents.states[0, 11, 0]))
    with pytest.raises(InputError, match="window 9 does not exist"):
        LangTrajEnv(long, window=9).reset(seed=0)


def test_a_long_ego_turns_as_wide_as_the_models_long_vehicles():
    from langtraj.env.environment import ego_curvature
    from langtraj.model.config import ModelConfig
    from langtraj.scenario.types import AgentType, StateField

    scenario = follower_scene()
    row = int(np.flatnonzero(scenario.agents.ids == EGO_ID)[0])
    assert ego_curvature(scenario, row) == pytest.approx(ModelConfig().vehicle_max_curvature)  # a car: the flat bound
    scenario.agents.states[row, :, StateField.LENGTH] = 12.0  # a bus
    assert ego_curvature(scenario, row) == pytest.approx(1 / (ModelConfig().turn_radius_per_length * 12.0))
    scenario.agents.types[row] = AgentType.PEDESTRIAN
    assert ego_curvature(scenario, row) == float("inf")


def test_the_others_last_second_is_in_the_observation():
    """`agents_history`: each listed agent's positions at the 10 steps before now, in the ego frame of now, oldest
    first: the log's history at reset, the played steps after (checked against `played()` in world coordinates)."""
    env = LangTrajEnv(follower_scene(speed=8.0), policy="log_replay")
    obs, _ = env.reset(seed=0)
    for step in range(4):
        if step:
            obs, *_ = env.step(np.array([2.0, 0.0]))  # the ego speeds up: the frame moves against the others
        played = env.played()
        x, y, heading = (float(v) for v in obs["ego"][[EgoColumn.X, EgoColumn.Y, EgoColumn.HEADING]])
        c, s = np.cos(heading), np.sin(heading)
        listed = np.flatnonzero(obs["agents_valid"])
        assert len(listed) == 3 and obs["agents_history_valid"][listed].all()
        for k in listed:
            row = played.agents.index_of(int(obs["agents_id"][k]))
            world = played.agents.xy[row, -11:-1] - (x, y)  # the 10 steps before now
            expected = np.stack([c * world[:, 0] + s * world[:, 1], -s * world[:, 0] + c * world[:, 1]], axis=1)
            assert obs["agents_history"][k] == pytest.approx(expected, abs=1e-3)
        assert not obs["agents_history_valid"][len(listed) :].any() and observation_space().contains(obs)
