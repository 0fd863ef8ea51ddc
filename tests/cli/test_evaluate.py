"""`langtraj evaluate` and `langtraj baseline` end to end: single files, rollout folders, bad input."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scenario_builders import make_scenario

from langtraj.cli.main import main
from langtraj.metrics.corpus import EvalJob, aggregate, evaluate_corpus, pair_jobs, run_job
from langtraj.rollouts import Rollouts
from langtraj.rollouts.baselines import generate_baseline
from langtraj.scenario.io import write_scenarios


@pytest.fixture
def corpus(tmp_path: Path) -> tuple[Path, Path]:
    """A WOMD file of three toy scenes and a folder with log-replay rollouts for two of them."""
    scenes = [make_scenario(5, scenario_id=f"toy{i}", seed=i) for i in range(3)]
    scenario_file = tmp_path / "scenes.tfrecord"
    write_scenarios(scenario_file, scenes)
    rollouts = tmp_path / "rollouts"
    for scene in scenes[:2]:
        generate_baseline("log_replay", scene, 4, seed=1, noise_std=0.1).save(rollouts / f"{scene.scenario_id}.npz")
    return scenario_file, rollouts


def run_cli(argv: list[str], capsys) -> tuple[int, str, str]:
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_single_file_json_has_every_field(corpus, capsys, tmp_path):
    scenario_file, rollouts = corpus
    out = tmp_path / "report.json"
    code, stdout, _ = run_cli(
        ["evaluate", str(scenario_file), str(rollouts / "toy1.npz"), "--index", "1", "--json", "--out", str(out)],
        capsys,
    )
    assert code == 0
    report = json.loads(stdout)
    assert report == json.loads(out.read_text())
    assert report["scenario_id"] == "toy1"
    for key in ("metametric", "kinematic_metrics", "interactive_metrics", "map_based_metrics"):
        assert 0.0 < report[key] <= 1.0
    assert report["min_average_displacement_error"] <= report["average_displacement_error"]


def test_folder_mode_scores_matching_scenes_and_averages(corpus, capsys):
    scenario_file, rollouts = corpus
    jobs = pair_jobs([scenario_file], rollouts)
    assert [(j.index, Path(j.rollouts_file).name) for j in jobs] == [(0, "toy0.npz"), (1, "toy1.npz")]
    singles = [run_job(j) for j in jobs]
    code, stdout, _ = run_cli(["evaluate", str(scenario_file), str(rollouts), "--json"], capsys)
    assert code == 0
    report = json.loads(stdout)
    assert report["num_scenarios"] == 2
    assert [s["scenario_id"] for s in report["scenarios"]] == ["toy0", "toy1"]
    assert report["metametric"] == pytest.approx(np.mean([s.metametric for s in singles]))
    assert aggregate(singles)["min_average_displacement_error"] == pytest.approx(
        report["min_average_displacement_error"]
    )


def test_two_workers_give_the_same_figures(corpus):
    scenario_file, rollouts = corpus
    jobs = pair_jobs([scenario_file], rollouts)
    one = evaluate_corpus(jobs, workers=1, progress=False)
    two = evaluate_corpus(jobs, workers=2, progress=False)
    assert [r.to_dict() for r in one] == [r.to_dict() for r in two]


def test_rollouts_for_an_unknown_scene_are_an_error(corpus, capsys):
    scenario_file, rollouts = corpus
    generate_baseline("stationary", make_scenario(5, scenario_id="elsewhere"), 2).save(rollouts / "elsewhere.npz")
    code, _, err = run_cli(["evaluate", str(scenario_file), str(rollouts)], capsys)
    assert code == 2
    assert "elsewhere" in err and "not in the scenario files" in err


def _broken(scene, how: str) -> Rollouts:
    good = generate_baseline("log_replay", scene, 4)
    if how == "missing agent":
        keep = np.arange(good.num_agents - 1)
        return Rollouts(good.object_id[keep], good.x[:, keep], good.y[:, keep], good.z[:, keep], good.heading[:, keep])
    if how == "79 steps":
        return Rollouts(good.object_id, good.x[..., :79], good.y[..., :79], good.z[..., :79], good.heading[..., :79])
    if how == "nan":
        x = good.x.copy()
        x[2, 1, 40] = np.nan
        return replace(good, x=x)
    if how == "inf":
        heading = good.heading.copy()
        heading[0, 0, 0] = np.inf
        return replace(good, heading=heading)
    if how == "other scenario":
        return replace(good, scenario_id="toy2")
    raise AssertionError(how)


@pytest.mark.parametrize(
    ("how", "message"),
    [
        ("missing agent", "missing sim agents"),
        ("79 steps", "79 steps per rollout, expected 80"),
        ("nan", "non-finite value at rollout 2"),
        ("inf", "heading: non-finite value at rollout 0"),
        ("other scenario", "rollouts are for scenario 'toy2', not 'toy0'"),
    ],
)
def test_bad_rollouts_give_one_clear_line_and_no_report(corpus, capsys, tmp_path, how, message):
    scenario_file, _ = corpus
    bad = tmp_path / "bad.npz"
    _broken(make_scenario(5, scenario_id="toy0", seed=0), how).save(bad)
    report = tmp_path / "report.json"
    code, stdout, err = run_cli(["evaluate", str(scenario_file), str(bad), "--out", str(report)], capsys)
    assert code == 2
    assert message in err and str(bad) in err
    assert len(err.strip().splitlines()) == 1
    assert not report.exists() and stdout == ""


def test_a_scene_without_80_logged_future_steps_cannot_be_scored(tmp_path, capsys):
    short = make_scenario(5, num_steps=60, scenario_id="short")
    scenario_file = tmp_path / "short.tfrecord"
    write_scenarios(scenario_file, [short])
    rollouts = tmp_path / "r.npz"
    long_scene = make_scenario(5, scenario_id="short")
    generate_baseline("stationary", long_scene, 2).save(rollouts)
    code, _, err = run_cli(["evaluate", str(scenario_file), str(rollouts)], capsys)
    assert code == 2 and "logs 49 future steps; scoring needs 80" in err


def test_a_corrupt_rollout_file_names_the_file(tmp_path, capsys, corpus):
    scenario_file, _ = corpus
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"PK\x03\x04 not really a zip")
    code, _, err = run_cli(["evaluate", str(scenario_file), str(junk)], capsys)
    assert code == 2 and str(junk) in err


def test_baseline_verb_writes_rollouts_that_evaluate_scores(corpus, capsys, tmp_path):
    scenario_file, _ = corpus
    out = tmp_path / "cv.npz"
    code, stdout, _ = run_cli(
        ["baseline", str(scenario_file), "--index", "2", "--policy", "constant_velocity", "--out", str(out)], capsys
    )
    assert code == 0 and "constant_velocity" in stdout
    rollouts = Rollouts.load(out)
    assert rollouts.scenario_id == "toy2" and rollouts.num_rollouts == 32
    assert run_job(EvalJob(str(scenario_file), 2, str(out))).scenario_id == "toy2"
    code, _, err = run_cli(
        [
            "baseline",
            str(scenario_file),
            "--policy",
            "log_replay",
            "--noise-std",
            "nan",
            "--out",
            str(tmp_path / "x.npz"),
        ],
        capsys,
    )
    assert code == 2 and "noise_std" in err and not (tmp_path / "x.npz").exists()


def test_safety_and_controllability_blocks(corpus, capsys, tmp_path):
    scenario_file, rollouts = corpus
    scene = make_scenario(5, scenario_id="toy0", seed=0)
    stationary = tmp_path / "stationary.npz"
    generate_baseline("stationary", scene, 4).save(stationary)
    code, stdout, _ = run_cli(
        [
            "evaluate", str(scenario_file), str(rollouts / "toy0.npz"), "--json",
            "--adversary", "7", "--target", "17", "--unconditioned", str(stationary), "--agents", "7,17",
        ],
        capsys,
    )  # fmt: skip
    assert code == 0
    report = json.loads(stdout)
    assert report["safety"]["pair_collision_rate"] == 0.0
    control = report["controllability"]
    assert control["agent_ids"] == [7, 17]
    assert control["min_ade_conditioned"] < control["min_ade_unconditioned"]
    assert 0 < control["relative_reduction"] <= 1


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--adversary", "7"], "--adversary and --target go together"),
        (["--adversary", "7", "--target", "7"], "same object 7"),
        (["--adversary", "7", "--target", "9999"], "9999"),
        (["--agents", "7"], "--unconditioned and --agents go together"),
    ],
)
def test_bad_safety_arguments(corpus, capsys, extra, message):
    scenario_file, rollouts = corpus
    code, stdout, err = run_cli(["evaluate", str(scenario_file), str(rollouts / "toy0.npz"), *extra], capsys)
    assert code == 2 and message in err and stdout == ""
