"""Every registered policy runs through `langtraj simulate` on a shared real scene, built by its registry."""

from __future__ import annotations

import json

import numpy as np
import pytest

from langtraj.cli.main import main
from langtraj.rollouts.baselines import generate_baseline
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.io import read_scenario
from langtraj.sim.policies import POLICIES

WOMD = "motion_data_one_scenario.tfrecord"
PROMPT = "@2320 yields to @1676"  # two agents the shipped model drives in that scene


def _simulate(scene, out, *extra) -> int:
    fast = ["--rollouts", "1", "--candidates", "1", "--steps", "2", "--replan-s", "4", "--no-video"]
    return main(["simulate", str(scene), *fast, "--out", str(out), *extra])


@pytest.mark.real_data
@pytest.mark.parametrize("name", POLICIES.names())
def test_every_registered_policy_simulates_a_real_scene(name, real_data_dir, tmp_path, capsys):
    scene = real_data_dir / WOMD
    extra = ["--prompt", PROMPT] if name == "guidance_baseline" else []
    assert _simulate(scene, tmp_path / name, "--policy", name, *extra) == 0, capsys.readouterr().err
    summary = json.loads((tmp_path / name / "summary.json").read_text())
    assert summary["policy"] == name
    rollouts = Rollouts.load(tmp_path / name / "rollouts.npz")
    assert rollouts.x.shape[:2] == (1, len(read_scenario(scene).agents.ids[read_scenario(scene).agents.valid[:, 10]]))
    if name == "guidance_baseline":
        assert summary["prompted_ids"] == [2320, 1676]
        assert summary["prompt_read_as"]["subtype"].startswith("yielding/")
        assert summary["selector"] == "min_guidance"  # its costs steer the scene: selection keeps them
    if name == "langtraj":
        assert summary["selector"] == "per_agent"


@pytest.mark.real_data
def test_the_guidance_baseline_refuses_a_missing_or_unreadable_prompt(real_data_dir, tmp_path, capsys):
    scene = real_data_dir / WOMD
    assert _simulate(scene, tmp_path / "a", "--policy", "guidance_baseline") == 2
    assert "takes exactly one prompt" in capsys.readouterr().err
    assert _simulate(scene, tmp_path / "b", "--policy", "guidance_baseline", "--prompt", "@2320 dances") == 2
    err = capsys.readouterr().err
    assert "needs a prompt whose behaviour it can read" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.real_data
def test_the_constant_velocity_policy_gives_the_wosac_baseline(real_data_dir, tmp_path):
    scene = real_data_dir / WOMD
    out = tmp_path / "cv"
    assert main(["simulate", str(scene), "--policy", "constant_velocity", "--rollouts", "2", "--no-video",
                 "--out", str(out)]) == 0  # fmt: skip
    simulated = Rollouts.load(out / "rollouts.npz")
    reference = generate_baseline("constant_velocity", read_scenario(scene), 2)
    assert np.array_equal(simulated.object_id, reference.object_id)
    for field in ("x", "y", "heading"):
        np.testing.assert_allclose(getattr(simulated, field), getattr(reference, field), atol=1e-3)
