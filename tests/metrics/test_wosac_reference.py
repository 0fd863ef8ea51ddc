"""Agreement with the official WOSAC implementation on the shared reference rollouts.

The reference folder holds rollouts of four policies for Waymo scenario 637f20cafde22ff8 and the
figures the official implementation (waymo-open-dataset 1.6.7) computed for them under the 2024 and
2025 configurations. Every likelihood, bucket and the meta-metric must agree within 0.005, and the
simulated rates exactly.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from langtraj.cli.main import main
from langtraj.metrics.wosac import evaluate_scenario
from langtraj.rollouts import Rollouts
from langtraj.scenario.io import read_scenario

POLICIES = ("const_vel", "log", "log_noise0.05", "stationary")
RATES = ("simulated_collision_rate", "simulated_offroad_rate", "simulated_traffic_light_violation_rate")
TOLERANCE = 0.005

pytestmark = pytest.mark.real_data


@pytest.fixture(scope="module")
def womd_scenario(real_data_dir: Path):
    return read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord")


@pytest.fixture(scope="module")
def official(wosac_reference: Path) -> dict:
    return json.loads((wosac_reference / "official_metrics.json").read_text())


@pytest.mark.parametrize("config", ["2025", "2024"])
@pytest.mark.parametrize("policy", POLICIES)
def test_every_figure_agrees_with_the_official_implementation(womd_scenario, official, wosac_reference, policy, config):
    name = f"rollouts_637f20cafde22ff8_{policy}.npz"
    expected = official[name][config]
    ours = evaluate_scenario(womd_scenario, Rollouts.load(wosac_reference / name), config).to_dict()
    compared = [k for k in expected if k != "metametric_weights"]
    assert len(compared) == 19
    for key in compared:
        if key in RATES:
            assert ours[key] == pytest.approx(expected[key], abs=1e-9), key
        else:
            assert abs(ours[key] - expected[key]) <= TOLERANCE, (key, ours[key], expected[key])


def test_the_weights_are_the_official_ones(official):
    from langtraj.metrics.config import wosac_config

    for config in ("2025", "2024"):
        weights = next(iter(official.values()))[config]["metametric_weights"]
        ours = wosac_config(config)
        for feature, weight in weights.items():
            assert ours.weight(feature) == pytest.approx(weight, abs=1e-7), (config, feature)


def test_the_cli_prints_the_official_json_keys(real_data_dir, wosac_reference, official, capsys):
    rollouts = wosac_reference / "rollouts_637f20cafde22ff8_const_vel.npz"
    scenario_file = real_data_dir / "motion_data_one_scenario.tfrecord"
    assert main(["evaluate", str(scenario_file), str(rollouts), "--config", "2024", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    expected = official[rollouts.name]["2024"]
    for key in ("metametric", "kinematic_metrics", "interactive_metrics", "map_based_metrics"):
        assert abs(report[key] - expected[key]) <= TOLERANCE
    assert {k for k in expected if k != "metametric_weights"} <= set(report)
