"""The rollout baselines on constructed scenes, and against the WOSAC reference rollouts of the real scene."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scenario_builders import make_scenario

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.rollouts import Rollouts, sim_agent_indices
from langtraj.rollouts.baselines import (
    BASELINES,
    ConstantVelocity,
    LogReplay,
    RolloutBaseline,
    Stationary,
    generate_baseline,
)
from langtraj.rollouts.validation import check_rollouts
from langtraj.scenario import FUTURE_STEPS, Agents, AgentType, Scenario, StateField
from langtraj.scenario.io import read_scenario
from langtraj.scenario.io.tfrecord import iter_records
from langtraj.scenario.io.womd import decode_scenario

WOMD_ID = "637f20cafde22ff8"
WOMD_FILE = "motion_data_one_scenario.tfrecord"
REFERENCE = {"constant_velocity": "const_vel", "log_replay": "log", "stationary": "stationary"}
C = 10  # current step of the constructed scenes


def scene(states: np.ndarray, valid: np.ndarray, *, current: int = C, scenario_id: str = "built") -> Scenario:
    """A map-less scene of vehicles 101, 102, ... with `states` [A, T, 9] and `valid` [A, T]."""
    num, steps = valid.shape
    return Scenario(
        scenario_id=scenario_id,
        timestamps=np.arange(steps) * 0.1,
        current_index=current,
        sdc_index=-1,
        agents=Agents(
            ids=np.arange(num) + 101, types=np.full(num, AgentType.VEHICLE, np.int8), states=states, valid=valid
        ),
    )


def track(steps: int, start, step, heading: float = 0.0) -> np.ndarray:
    """States [steps, 9] moving by `step` (x, y, z) per step from `start`, velocity consistent, heading fixed."""
    out = np.zeros((steps, 9))
    out[:, :3] = np.asarray(start, float) + np.arange(steps)[:, None] * np.asarray(step, float)
    out[:, StateField.HEADING] = heading
    out[:, StateField.VX : StateField.VY + 1] = np.asarray(step[:2], float) * 10
    out[:, StateField.LENGTH :] = (4.5, 2.0, 1.6)
    return out


def future_steps(first: int = 1) -> np.ndarray:
    """Steps ahead of the current one for each output step: 1 .. 80."""
    return np.arange(first, first + FUTURE_STEPS)


# ---------------------------------------------------------------------------- registry and options


def test_three_baselines_are_registered():
    assert set(BASELINES.names()) == {"constant_velocity", "log_replay", "stationary"}
    assert all(issubclass(cls, RolloutBaseline) for cls in BASELINES.classes())
    assert {cls.name for cls in (ConstantVelocity, LogReplay, Stationary)} == set(BASELINES.names())


def test_unknown_name_bad_options_and_counts_raise_input_error():
    s = make_scenario()
    with pytest.raises(InputError, match=r"unknown rollout baseline 'replay'.*log_replay"):
        generate_baseline("replay", s)
    with pytest.raises(InputError, match=r"baseline stationary.*noise_std"):
        generate_baseline("stationary", s, noise_std=0.1)
    with pytest.raises(InputError, match="noise_std"):
        generate_baseline("log_replay", s, noise_std=-1.0)
    with pytest.raises(InputError, match="noise_std"):
        LogReplay(noise_std=math.nan)
    with pytest.raises(InputError, match="num_rollouts"):
        generate_baseline("constant_velocity", s, 0)


@pytest.mark.parametrize("name", ["constant_velocity", "log_replay", "stationary"])
def test_output_layout_is_the_wosac_one(name):
    s = make_scenario()  # agent 2 (id 27) is invalid at the current step: not a sim agent
    r = generate_baseline(name, s)
    assert isinstance(r, Rollouts) and r.scenario_id == "toy"
    assert (r.num_rollouts, r.num_agents, r.num_steps) == (32, 3, FUTURE_STEPS)
    np.testing.assert_array_equal(r.object_id, s.agents.ids[sim_agent_indices(s)])
    assert r.object_id.tolist() == [7, 17, 37]
    assert all(getattr(r, n).dtype == np.float32 for n in ("x", "y", "z", "heading"))
    check_rollouts(s, r, num_rollouts=32)
    assert generate_baseline(name, s, 5).num_rollouts == 5
    for n in ("x", "y", "z", "heading"):  # deterministic baselines: identical rollouts
        arr = getattr(r, n)
        assert (arr == arr[:1]).all()


# ---------------------------------------------------------------------------- constant velocity and stationary


def test_constant_velocity_keeps_the_last_displacement_or_the_velocity():
    states = np.stack(
        [track(91, (5.0, -2.0, 1.0), (1.0, 0.5, 0.02), 0.3), track(91, (0, 0, 2.0), (0.3, -0.4, 0.1), -2)]
    )
    valid = np.ones((2, 91), bool)
    valid[1, C - 1] = False  # no previous step: velocity (3, -4) m/s times 0.1 s, no vertical motion
    states[1, C - 1, :3] = np.nan
    states[1, C, StateField.VX : StateField.VY + 1] = (3.0, -4.0)
    r = generate_baseline("constant_velocity", scene(states, valid), 2)
    k = future_steps()
    np.testing.assert_allclose(r.x[0, 0], 5.0 + (C + k) * 1.0, atol=1e-4)
    np.testing.assert_allclose(r.y[0, 0], -2.0 + (C + k) * 0.5, atol=1e-4)
    np.testing.assert_allclose(r.z[0, 0], 1.0 + (C + k) * 0.02, atol=1e-4)
    np.testing.assert_allclose(r.heading[0, 0], 0.3, atol=1e-6)
    np.testing.assert_allclose(r.x[0, 1], C * 0.3 + k * 0.3, atol=1e-4)
    np.testing.assert_allclose(r.y[0, 1], C * -0.4 - k * 0.4, atol=1e-4)
    np.testing.assert_allclose(r.z[0, 1], 2.0 + C * 0.1, atol=1e-5)
    np.testing.assert_allclose(r.heading[0, 1], -2.0, atol=1e-6)


def test_constant_velocity_at_step_zero_uses_the_velocity():
    states = track(91, (0, 0, 0), (0.2, 0.1, 0.5))[None]
    r = generate_baseline("constant_velocity", scene(states, np.ones((1, 91), bool), current=0), 1)
    np.testing.assert_allclose(r.x[0, 0], 0.2 * future_steps(), atol=1e-5)
    np.testing.assert_allclose(r.z[0, 0], 0.0, atol=1e-6)


def test_stationary_freezes_the_current_pose():
    s = make_scenario()
    r = generate_baseline("stationary", s, 3)
    now = s.agents.states[sim_agent_indices(s), s.current_index]
    for n, col in (("x", 0), ("y", 1), ("z", 2), ("heading", 3)):
        np.testing.assert_array_equal(getattr(r, n), np.broadcast_to(now[None, :, col, None], r.x.shape))


# ---------------------------------------------------------------------------- log replay


def test_log_replay_is_the_log_where_valid():
    s = make_scenario()
    r = generate_baseline("log_replay", s, 2)
    agents = sim_agent_indices(s)
    future = s.agents.states[agents, C + 1 :]
    np.testing.assert_array_equal(r.x[0], future[..., 0])
    np.testing.assert_array_equal(r.y[1], future[..., 1])
    np.testing.assert_array_equal(r.z[0], future[..., 2])
    np.testing.assert_array_equal(r.heading[0], future[..., 3])


def test_log_replay_interpolates_gaps_with_unwrapped_heading():
    states = track(91, (0, 0, 0), (1.0, 0.2, 0.01), 3.0)[None]
    valid = np.ones((1, 91), bool)
    valid[0, 21:25] = False  # gap between steps 20 and 25
    states[0, 21:25, :4] = np.nan
    states[0, 25:, StateField.HEADING] = -3.0  # crossing +-pi: the short way is through pi
    r = generate_baseline("log_replay", scene(states, valid), 1)
    gap = np.arange(21, 25)
    out = gap - C - 1
    np.testing.assert_allclose(r.x[0, 0, out], gap * 1.0, atol=1e-5)
    np.testing.assert_allclose(r.y[0, 0, out], gap * 0.2, atol=1e-5)
    np.testing.assert_allclose(r.z[0, 0, out], gap * 0.01, atol=1e-5)
    turn = 2 * math.pi - 6.0  # from 3.0 up through pi to -3.0 (= 3.0 + turn)
    expected = wrap_angle(3.0 + turn * (gap - 20) / 5)
    np.testing.assert_allclose(wrap_angle(r.heading[0, 0, out] - expected), 0.0, atol=1e-6)
    assert (np.abs(r.heading[0, 0, out]) > 3.0).all()  # never swept through 0
    assert (r.heading <= np.float32(math.pi)).all() and (r.heading >= -np.float32(math.pi)).all()


def test_log_replay_extends_after_the_last_valid_state():
    moving = track(91, (0, 0, 0), (1.0, 0.5, 0.1), 0.7)
    skipping = track(91, (0, 10, 0), (0.5, 0.0, 0.2), -0.4)  # last valid 40, 39 invalid: velocity, no z motion
    skipping[40, StateField.VX : StateField.VY + 1] = (2.0, 1.0)
    lonely = track(91, (0, 20, 0), (0.3, 0.1, 0.05), 1.2)  # no valid future: as constant velocity
    states = np.stack([moving, skipping, lonely])
    valid = np.ones((3, 91), bool)
    valid[0, 51:] = False
    valid[1, 41:] = False
    valid[1, 39] = False
    valid[2, C + 1 :] = False
    states[~valid, :3] = np.nan
    s = scene(states, valid)
    r = generate_baseline("log_replay", s, 1)
    steps = C + future_steps()
    after = steps > 50
    np.testing.assert_allclose(r.x[0, 0], steps * 1.0, atol=1e-4)  # log then its continuation
    np.testing.assert_allclose(r.y[0, 0], steps * 0.5, atol=1e-4)
    np.testing.assert_allclose(r.z[0, 0], steps * 0.1, atol=1e-4)
    np.testing.assert_allclose(r.heading[0, 0, after], 0.7, atol=1e-6)
    after = steps > 40
    np.testing.assert_allclose(r.x[0, 1, after], 20.0 + (steps[after] - 40) * 0.2, atol=1e-4)
    np.testing.assert_allclose(r.y[0, 1, after], 10.0 + (steps[after] - 40) * 0.1, atol=1e-4)
    np.testing.assert_allclose(r.z[0, 1, after], 8.0, atol=1e-5)
    np.testing.assert_allclose(r.z[0, 1, steps == 39], 7.8, atol=1e-5)  # interpolated between 38 and 40
    cv = generate_baseline("constant_velocity", s, 1)
    for n in ("x", "y", "z", "heading"):
        np.testing.assert_array_equal(getattr(r, n)[:, 2], getattr(cv, n)[:, 2])


def test_log_replay_extends_a_short_log_by_constant_velocity():
    states = track(40, (1, 2, 3), (0.4, -0.2, 0.05), 0.1)[None]
    r = generate_baseline("log_replay", scene(states, np.ones((1, 40), bool)), 1)
    steps = C + future_steps()
    assert r.num_steps == FUTURE_STEPS
    np.testing.assert_allclose(r.x[0, 0], 1 + 0.4 * steps, atol=1e-4)
    np.testing.assert_allclose(r.y[0, 0], 2 - 0.2 * steps, atol=1e-4)
    np.testing.assert_allclose(r.z[0, 0], 3 + 0.05 * steps, atol=1e-4)


def test_log_replay_noise_is_seeded_gaussian_on_xy_and_heading():
    s = make_scenario()
    clean = generate_baseline("log_replay", s)
    a = generate_baseline("log_replay", s, seed=7, noise_std=0.2)
    b = generate_baseline("log_replay", s, seed=7, noise_std=0.2)
    c = generate_baseline("log_replay", s, seed=8, noise_std=0.2)
    for n in ("x", "y", "z", "heading"):
        np.testing.assert_array_equal(getattr(a, n), getattr(b, n))
    assert not np.array_equal(a.x, c.x)
    np.testing.assert_array_equal(a.z, clean.z)
    assert (a.x[0] != a.x[1]).mean() > 0.99  # rollouts differ
    for n, std in (("x", 0.2), ("y", 0.2), ("heading", 0.02)):
        residual = wrap_angle(getattr(a, n) - getattr(clean, n))
        assert residual.std() == pytest.approx(std, rel=0.05)
        assert abs(residual.mean()) < 0.05 * std
        assert abs(np.corrcoef(residual[:, :, 1:].ravel(), residual[:, :, :-1].ravel())[0, 1]) < 0.05
    zero = generate_baseline("log_replay", s, seed=7, noise_std=0.0)
    np.testing.assert_array_equal(zero.x, clean.x)


# ---------------------------------------------------------------------------- the WOSAC reference files


@pytest.fixture(scope="module")
def reference_dir(wosac_reference: Path) -> Path:
    return wosac_reference


@pytest.fixture(scope="module")
def womd_scene(real_data_dir: Path) -> Scenario:
    return read_scenario(real_data_dir / WOMD_FILE)


@pytest.fixture(scope="module")
def womd_float64(real_data_dir: Path, womd_scene: Scenario) -> np.ndarray:
    """The sim agents' states [A, 91, 6] (x, y, z, heading, vx, vy) in the proto's own precision (float64)."""
    msg = decode_scenario(next(iter(iter_records(real_data_dir / WOMD_FILE))))
    assert msg.scenario_id == WOMD_ID
    fields = ("center_x", "center_y", "center_z", "heading", "velocity_x", "velocity_y")
    states = np.array([[[getattr(s, f) for f in fields] for s in t.states] for t in msg.tracks], np.float64)
    return states[sim_agent_indices(womd_scene)]


def load_reference(reference_dir: Path, policy: str) -> Rollouts:
    return Rollouts.load(reference_dir / f"rollouts_{WOMD_ID}_{policy}.npz")


def assert_heading_close(actual: np.ndarray, expected: np.ndarray, atol: float = 1e-5) -> None:
    assert np.abs(wrap_angle(actual - expected)).max() <= atol


@pytest.mark.real_data
@pytest.mark.parametrize("name", list(REFERENCE))
def test_reference_rules_reproduced_exactly_from_the_float64_log(name, reference_dir, womd_scene, womd_float64):
    """The reference was computed from the proto's float64 positions: the same input gives the same output."""
    ref = load_reference(reference_dir, REFERENCE[name])
    poses = BASELINES.create(name).poses(womd_float64, womd_scene.agents.valid[sim_agent_indices(womd_scene)], 10)
    poses = poses.astype(np.float32)
    for col, n in enumerate(("x", "y", "z")):
        np.testing.assert_allclose(getattr(ref, n), np.broadcast_to(poses[..., col], ref.x.shape), rtol=0, atol=1e-4)
    assert_heading_close(ref.heading, poses[..., 3])


@pytest.mark.real_data
@pytest.mark.parametrize("name", list(REFERENCE))
def test_reference_reproduced_from_the_scenario(name, reference_dir, womd_scene):
    """From the float32 Scenario the output may differ by the input's rounding, growing with the steps
    extrapolated (one float32 spacing of the coordinate per step); headings match to 1e-5."""
    ref = load_reference(reference_dir, REFERENCE[name])
    ours = generate_baseline(name, womd_scene)
    np.testing.assert_array_equal(ours.object_id, ref.object_id)
    assert ours.scenario_id == WOMD_ID
    for n in ("x", "y", "z"):
        expected = getattr(ref, n)
        spacing = np.spacing(np.abs(expected).max(axis=(0, 2), keepdims=True))
        bound = 1e-4 + future_steps()[None, None, :] * spacing
        assert (np.abs(getattr(ours, n) - expected) <= bound).all(), n
        if n != "z":  # z (about -184 m, spacing 1.5e-5) drifts for most moving agents; x and y for a few
            close = np.abs(getattr(ours, n) - expected).max(axis=(0, 2)) <= 1e-4
            assert close.mean() >= 0.95, n
    assert_heading_close(ours.heading, ref.heading)


@pytest.mark.real_data
def test_noisy_reference_statistics_match(reference_dir, womd_scene):
    log = load_reference(reference_dir, "log")
    noisy = load_reference(reference_dir, "log_noise0.05")
    ours = generate_baseline("log_replay", womd_scene, seed=1, noise_std=0.05)
    clean = generate_baseline("log_replay", womd_scene)
    for n, std in (("x", 0.05), ("y", 0.05), ("heading", 0.005)):
        ref_residual = wrap_angle(getattr(noisy, n) - getattr(log, n))
        our_residual = wrap_angle(getattr(ours, n) - getattr(clean, n))
        assert ref_residual.std() == pytest.approx(std, rel=0.03)
        assert our_residual.std() == pytest.approx(ref_residual.std(), rel=0.03)
    np.testing.assert_array_equal(noisy.z, log.z)
    np.testing.assert_array_equal(ours.z, clean.z)
