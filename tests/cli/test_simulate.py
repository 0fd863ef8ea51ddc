"""`langtraj simulate` end to end: the three outputs, the driven-agent report, and bad inputs refused
before anything is written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cli.helpers import METADATA
from langtraj.cli.main import main
from langtraj.rollouts.container import Rollouts
from langtraj.rollouts.validation import check_rollouts
from langtraj.scenario.io import read_scenario


def test_simulate_writes_rollouts_video_and_summary(tiny_run, tmp_path, capsys):
    checkpoint, scenes = tiny_run
    out = tmp_path / "sim"
    code = main(["simulate", str(scenes), "--checkpoint", str(checkpoint), "--prompt", "@7 yields to @17",
                 "--adversary", "37", "--target", "7", "--rollouts", "2", "--candidates", "2", "--steps", "2",
                 "--replan-s", "4", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    printed = capsys.readouterr().out
    assert "4 agents moved by langtraj" in printed
    assert 'prompt: read as: @7 yield @17 ("yields to @17")' in printed  # what was read, and what steered it
    rollouts = Rollouts.load(out / "rollouts.npz")
    check_rollouts(read_scenario(scenes), rollouts, num_rollouts=2)
    assert (out / "rollout0.mp4").stat().st_size > 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["prompted_ids"] == [7, 17] and summary["guidance"] == ["collision=1"]
    assert summary["on_road"] == 1.0 and summary["selector"] == "min_guidance"  # the defaults with guidance
    assert summary["attention"] == "local"
    assert summary["prompt_levers"] == ["text", "guidance", "selection"]
    (read,) = summary["prompt"]["read"]
    assert (read["behaviour"], read["agent"], read["other"]) == ("yield", 7, 17)
    assert summary["prompt"]["steering"][0].endswith("adherence-first selection")
    assert summary["replans"] == [10, 50] and len(summary["seconds_per_replan"]) == 2
    agents = {a["id"]: a for a in summary["agents"]}
    assert set(agents) == {7, 17, 37, 47} and all(a["driven"] for a in agents.values())
    assert summary["agents_by_policy"] == {"langtraj": [7, 17, 37, 47]} and not summary["reads_future_log"]
    assert 0.0 <= summary["map_coverage"]["start"] <= 1.0 and summary["map_pieces"] > 0
    assert all(0.0 <= a["collision_rate"] <= 1.0 and a["distance_m"] >= 0.0 for a in agents.values())
    # the rollouts score with `langtraj evaluate`
    assert main(["evaluate", str(scenes), str(out / "rollouts.npz"), "--json"]) == 0


def test_each_lever_of_a_prompt_can_be_switched_off_and_an_unread_prompt_steers_by_text(tiny_run, tmp_path, capsys):
    checkpoint, scenes = tiny_run
    out = tmp_path / "levers"
    code = main(["simulate", str(scenes), "--checkpoint", str(checkpoint), "--prompt", "@7 does a little dance",
                 "--no-prompt-guidance", "--no-prompt-selection", "--rollouts", "1", "--candidates", "2",
                 "--steps", "2", "--replan-s", "4", "--no-video", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["prompt_levers"] == ["text"] and summary["selector"] == "per_agent"
    assert summary["prompt"]["steering"][0].startswith("not read:")
    assert "it steers by its text alone" in summary["prompt"]["steering"][0]


def test_a_capped_model_leaves_the_rest_to_constant_velocity_and_says_so(tiny_run, tmp_path, capsys):
    checkpoint, scenes = tiny_run
    out = tmp_path / "capped"
    code = main(["simulate", str(scenes), "--checkpoint", str(checkpoint), "--max-driven", "2", "--rollouts", "2",
                 "--candidates", "2", "--steps", "2", "--replan-s", "4", "--no-video", "--dense-attention",
                 "--warm-steps", "1", "--temperature", "0.8", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert "2 agents moved by langtraj; 2 agents moved by constant_velocity" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["attention"] == "dense"
    assert summary["agents_by_policy"] == {"langtraj": [7, 17], "constant_velocity": [37, 47]}
    assert summary["on_road"] == 1.0 and summary["selector"] == "per_agent"  # the defaults without guidance
    assert summary["guided_steps"] in (1, 2)  # of --steps 2: the defaults' guidance at the last ones
    assert summary["warm_steps"] == 1 and summary["temperature"] == 0.8
    assert not Rollouts.load(out / "rollouts.npz").reads_future_log


def test_log_following_is_flagged_by_simulate_and_evaluate_and_refused_by_submit(tiny_run, tmp_path, capsys):
    checkpoint, scenes = tiny_run
    out = tmp_path / "log"
    code = main(["simulate", str(scenes), "--checkpoint", str(checkpoint), "--max-driven", "2", "--undriven", "log",
                 "--rollouts", "2", "--candidates", "2", "--steps", "2", "--replan-s", "4", "--no-video",
                 "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert "WARNING" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reads_future_log"] and summary["agents_by_policy"]["log"] == [37, 47]
    assert main(["evaluate", str(scenes), str(out / "rollouts.npz")]) == 0
    assert "replay their logged future" in capsys.readouterr().err
    meta = tmp_path / "meta.json"
    meta.write_text(json.dumps(METADATA))
    folder = tmp_path / "folder"
    folder.mkdir()
    (folder / f"{read_scenario(scenes).scenario_id}.npz").write_bytes((out / "rollouts.npz").read_bytes())
    assert main(["submit", str(scenes), str(folder), "--metadata", str(meta), "--out", str(tmp_path / "sub")]) == 2
    assert "log_following_ids" in capsys.readouterr().err and not (tmp_path / "sub").exists()


def test_baseline_policies_need_no_checkpoint(tiny_run, tmp_path):
    _, scenes = tiny_run
    for policy in ("constant_velocity", "log_replay"):
        out = tmp_path / policy
        assert (
            main(["simulate", str(scenes), "--policy", policy, "--rollouts", "2", "--no-video", "--out", str(out)]) == 0
        )
        assert Rollouts.load(out / "rollouts.npz").x.shape == (2, 4, 80)
        assert not (out / "rollout0.mp4").exists()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--prompt", "@999 turns left"], "unknown agent @999"),
        (
            ["--prompt", "@7 turns left", "--prompt", "@7 stops"],
            "@7 is named by prompt 1 too",
        ),  # the one prompt check: the studio says the same
        (["--adversary", "7", "--target", "7"], "same agent"),
        (["--adversary", "27", "--target", "7"], "@27 is not an agent of this scene at its current step"),
        (["--adversary", "7"], "an adversary needs a target"),
        (["--guidance", "goal=1"], "'goal' cannot be given here"),
        (["--guidance", "on_road=-1"], "must be finite and >= 0"),
        (["--guidance", "on_road"], "expected NAME=WEIGHT"),
        (["--policy", "constant_velocity", "--prompt", "@7 stops"], "--prompt needs a model policy"),
        (
            ["--policy", "constant_velocity", "--max-driven", "2", "--rolling"],
            "--rolling and --max-driven need a model",
        ),
        (["--max-driven", "0"], "must be >= 1"),
        (["--on-road", "-1"], "must be finite and >= 0"),
        (["--guided-steps", "6"], "--guided-steps: must be in [1, 5]"),
        (["--policy", "constant_velocity", "--guided-steps", "1"], "--guided-steps needs a model policy"),
        (["--warm-steps", "6"], "--warm-steps: must be in [1, 5]"),
        (["--temperature", "0"], "--temperature: must be in"),
        (["--policy", "constant_velocity", "--warm-steps", "1"], "--warm-steps needs a model policy"),
        (["--selector", "best"], "best"),
        (["--policy", "constant_velocity", "--selector", "per_agent"], "--selector needs a model policy"),
        (["--policy", "constant_velocity", "--dense-attention"], "--dense-attention needs a model policy"),
        (["--policy", "constant_velocity", "--no-prompt-text"], "--no-prompt-text needs a model policy"),
        (["--policy", "teleport"], "unknown policy"),
        (["--replan-s", "0.25"], "replan_s"),
    ],
)
def test_bad_input_is_refused_and_nothing_is_written(tiny_run, tmp_path, capsys, extra, message):
    checkpoint, scenes = tiny_run
    out = tmp_path / "sim"
    code = main(["simulate", str(scenes), "--checkpoint", str(checkpoint), "--out", str(out), *extra])
    assert code == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_a_checkpoint_of_another_model_version_is_refused(tiny_run, tmp_path, capsys):
    import torch

    checkpoint, scenes = tiny_run
    state = torch.load(checkpoint, weights_only=True)
    state["langtraj_format"] = 999
    foreign = tmp_path / "foreign.ckpt"
    torch.save(state, foreign)
    out = tmp_path / "sim"
    assert main(["simulate", str(scenes), "--checkpoint", str(foreign), "--out", str(out)]) == 2
    assert "checkpoint" in capsys.readouterr().err and not out.exists()


def test_collision_guidance_pulls_the_adversary_to_its_target(tiny_run):
    from langtraj.guidance import CollisionCost, GuidanceTerm
    from langtraj.model.checkpoint import load_model
    from langtraj.sim import LangTrajPolicy, SimConfig, SimRequest, simulate

    checkpoint, scenes = tiny_run
    model, data = load_model(checkpoint)
    scenario = read_scenario(scenes)
    distances = []
    for terms in ((), (GuidanceTerm(CollisionCost(2, 0), 1.0),)):  # slots: 7 -> 0, 37 -> 2 (see summary test)
        policy = LangTrajPolicy(model, data, SimRequest(candidates=2, steps=3, guidance_scale=5.0), terms=terms)
        r = simulate(scenario, policy, SimConfig(rollouts=2, replan_s=2.0)).rollouts
        ids = list(r.object_id)
        a, t = ids.index(37), ids.index(7)
        distances.append(np.hypot(r.x[:, a] - r.x[:, t], r.y[:, a] - r.y[:, t]).mean())
    assert distances[1] < distances[0] - 1.0
