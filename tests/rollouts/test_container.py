"""The Rollouts container (save, load and its errors) and `check_rollouts` (the WOSAC submission rules)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.rollouts import Rollouts
from langtraj.rollouts.baselines import generate_baseline
from langtraj.rollouts.validation import check_rollouts
from langtraj.scenario import FUTURE_STEPS, Scenario
from langtraj.scenario.io import read_scenario

from .test_baselines import REFERENCE, WOMD_FILE, WOMD_ID, load_reference

FIELDS = ("x", "y", "z", "heading")


def random_rollouts(num_rollouts: int = 3, ids=(7, 17, 37), steps: int = FUTURE_STEPS, scenario_id="toy") -> Rollouts:
    rng = np.random.default_rng(0)
    shape = (num_rollouts, len(ids), steps)
    arrays = {n: rng.normal(size=shape).astype(np.float32) for n in FIELDS}
    return Rollouts(object_id=np.array(ids, np.int64), scenario_id=scenario_id, **arrays)


def write_npz(path: Path, **arrays) -> Path:
    np.savez(path, **arrays)
    return path


def good_arrays(num_agents: int = 3) -> dict[str, np.ndarray]:
    r = random_rollouts(ids=tuple(range(1, num_agents + 1)))
    return {"object_id": r.object_id, **{n: getattr(r, n) for n in FIELDS}}


@pytest.fixture
def toy() -> Scenario:
    return make_scenario()  # sim agents 7, 17, 37 (27 is invalid at the current step)


# ---------------------------------------------------------------------------- save and load


@pytest.mark.parametrize("scenario_id", ["toy", ""])
def test_save_load_round_trip(tmp_path, scenario_id):
    r = random_rollouts(scenario_id=scenario_id)
    path = tmp_path / "r.npz"
    r.save(path)
    back = Rollouts.load(path)
    assert back.scenario_id == scenario_id
    np.testing.assert_array_equal(back.object_id, r.object_id)
    assert back.object_id.dtype == np.int64
    for n in FIELDS:
        np.testing.assert_array_equal(getattr(back, n), getattr(r, n))
        assert getattr(back, n).dtype == np.float32
    with np.load(path) as data:  # the reference layout, plus the optional scenario id
        assert set(data.files) == {"object_id", *FIELDS} | ({"scenario_id"} if scenario_id else set())


def test_save_is_atomic(tmp_path, monkeypatch):
    path = tmp_path / "r.npz"
    random_rollouts().save(path)
    random_rollouts(num_rollouts=2).save(path)  # overwrite in place
    assert [p.name for p in tmp_path.iterdir()] == ["r.npz"]
    assert Rollouts.load(path).num_rollouts == 2

    def broken(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", broken)
    with pytest.raises(OSError, match="disk full"):
        random_rollouts(num_rollouts=5).save(path)
    assert [p.name for p in tmp_path.iterdir()] == ["r.npz"]  # no temp file left, old file intact
    monkeypatch.undo()
    assert Rollouts.load(path).num_rollouts == 2


def test_load_missing_and_unreadable_files(tmp_path):
    with pytest.raises(InputError, match=r"nothing\.npz: no such file") as err:
        Rollouts.load(tmp_path / "nothing.npz")
    assert err.value.path == str(tmp_path / "nothing.npz")
    text = tmp_path / "text.npz"
    text.write_text("object_id,x\n1,2\n")
    with pytest.raises(InputError, match=r"text\.npz: not a readable \.npz"):
        Rollouts.load(text)
    truncated = tmp_path / "truncated.npz"
    random_rollouts().save(truncated)
    truncated.write_bytes(truncated.read_bytes()[:1000])
    with pytest.raises(InputError, match=r"truncated\.npz"):
        Rollouts.load(truncated)


def test_load_missing_array(tmp_path):
    arrays = good_arrays()
    del arrays["heading"]
    path = write_npz(tmp_path / "noheading.npz", **arrays)
    with pytest.raises(InputError, match=r"noheading\.npz: missing arrays heading"):
        Rollouts.load(path)


def test_load_mismatched_shapes(tmp_path):
    arrays = good_arrays()
    arrays["y"] = arrays["y"][:, :, :40]
    with pytest.raises(InputError, match=r"shapes\.npz: y: shape \(3, 3, 40\) differs"):
        Rollouts.load(write_npz(tmp_path / "shapes.npz", **arrays))
    arrays = good_arrays()
    arrays["object_id"] = arrays["object_id"][:2]
    with pytest.raises(InputError, match=r"agents\.npz: x: 3 agents for 2 object ids"):
        Rollouts.load(write_npz(tmp_path / "agents.npz", **arrays))
    arrays = good_arrays()
    arrays["z"] = arrays["z"][0]
    with pytest.raises(InputError, match=r"flat\.npz: z: expected shape \(rollouts, agents, steps\)"):
        Rollouts.load(write_npz(tmp_path / "flat.npz", **arrays))


def test_load_bad_object_ids(tmp_path):
    arrays = good_arrays()
    arrays["object_id"] = arrays["object_id"].astype(np.float64)
    with pytest.raises(InputError, match=r"float\.npz: object_id: expected a 1-D integer array"):
        Rollouts.load(write_npz(tmp_path / "float.npz", **arrays))
    arrays = good_arrays()
    arrays["object_id"] = np.array([4, 5, 4])
    with pytest.raises(InputError, match=r"repeat\.npz: object_id: repeated object ids"):
        Rollouts.load(write_npz(tmp_path / "repeat.npz", **arrays))


# ---------------------------------------------------------------------------- check_rollouts


def test_check_accepts_matching_rollouts_in_any_agent_order(toy):
    r = random_rollouts()
    np.testing.assert_array_equal(check_rollouts(toy, r, num_rollouts=3), [0, 1, 3])
    shuffled = dataclasses.replace(r, object_id=r.object_id[::-1].copy())
    np.testing.assert_array_equal(check_rollouts(toy, shuffled), [3, 1, 0])


def test_check_names_missing_and_extra_agents(toy):
    with pytest.raises(InputError, match=r"object_id: missing sim agents 37 \(scenario toy has 3 sim agents\)"):
        check_rollouts(toy, random_rollouts(ids=(7, 17)))
    with pytest.raises(InputError, match=r"missing sim agents 17; objects that are not sim agents .* 27, 99"):
        check_rollouts(toy, random_rollouts(ids=(7, 27, 37, 99)))


def test_check_counts(toy):
    with pytest.raises(InputError, match=r"steps: 79 steps per rollout, expected 80"):
        check_rollouts(toy, random_rollouts(steps=79))
    with pytest.raises(InputError, match=r"rollouts: 3 rollouts, expected 32"):
        check_rollouts(toy, random_rollouts(), num_rollouts=32)
    with pytest.raises(InputError, match="no rollouts"):
        check_rollouts(toy, random_rollouts(num_rollouts=0))


@pytest.mark.parametrize(("field", "value"), [("x", np.nan), ("heading", np.inf), ("z", -np.inf)])
def test_check_names_the_first_non_finite_value(toy, field, value):
    r = random_rollouts()
    getattr(r, field)[2, 1, 42] = value
    getattr(r, field)[2, 2, 50] = value
    with pytest.raises(InputError, match=rf"{field}: non-finite value at rollout 2, object 17, step 42 \(2 in all\)"):
        check_rollouts(toy, r)


def test_check_scenario_id(toy):
    with pytest.raises(InputError, match=r"scenario_id: rollouts are for scenario 'other', not 'toy'"):
        check_rollouts(toy, random_rollouts(scenario_id="other"))
    check_rollouts(toy, random_rollouts(scenario_id=""))  # no id: not checked


def test_generated_rollouts_pass_after_a_round_trip(toy, tmp_path):
    path = tmp_path / "cv.npz"
    generate_baseline("constant_velocity", toy).save(path)
    check_rollouts(toy, Rollouts.load(path), num_rollouts=32)


@pytest.fixture(scope="module")
def reference_dir(wosac_reference: Path) -> Path:
    return wosac_reference


@pytest.fixture(scope="module")
def womd_scene(real_data_dir: Path) -> Scenario:
    return read_scenario(real_data_dir / WOMD_FILE)


@pytest.mark.real_data
@pytest.mark.parametrize("policy", [*REFERENCE.values(), "log_noise0.05"])
def test_reference_files_pass(policy, reference_dir, womd_scene):
    ref = load_reference(reference_dir, policy)
    assert (ref.num_rollouts, ref.num_agents, ref.num_steps) == (32, 50, 80)
    order = check_rollouts(womd_scene, ref, num_rollouts=32)
    assert womd_scene.scenario_id == WOMD_ID
    np.testing.assert_array_equal(womd_scene.agents.ids[order], ref.object_id)
