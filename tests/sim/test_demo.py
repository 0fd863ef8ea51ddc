"""`langtraj demo` end to end on a tiny checkpoint: a synthesized scene simulated three ways, side by side."""

from __future__ import annotations

import json

import imageio.v3 as iio

from langtraj.cli.main import main
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.scenario.io import read_scenario


def test_demo_writes_three_panels_and_a_summary(tiny_run, tmp_path, capsys):
    checkpoint, _ = tiny_run
    out = tmp_path / "demo"
    assert main(["demo", "--checkpoint", str(checkpoint), "--out", str(out), "--candidates", "2"]) == 0
    printed = capsys.readouterr().out
    assert "safety-critical" in printed and "demo.mp4" in printed
    frames = iio.imread(out / "demo.mp4")
    assert frames.shape[0] == 91 and frames.shape[2] >= 3 * frames.shape[1] - 16  # three square panels
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["runs"]) == {"unconditioned", "prompt", "safety-critical"}
    safety = summary["runs"]["safety-critical"]
    assert safety["guidance"] == ["collision=1"] and safety["adversary"] == summary["adversary"]
    prompted = set(summary["runs"]["prompt"]["prompted_ids"])
    assert summary["target"] in prompted and prompted <= {summary["adversary"], summary["target"]}
    # the prompt asks for what the unconditioned run does not do, and each panel is judged against it
    assert set(summary["followed"]) == set(summary["runs"])
    assert all(0.0 <= share <= 1.0 for share in summary["followed"].values())
    if summary["prompt_kind"] == "counterfactual":
        assert summary["followed"]["unconditioned"] == 0.0 and summary["prompt"] != summary["logged_prompt"]
        assert summary["behaviour"] is not None
    else:
        assert summary["prompt"] == summary["logged_prompt"]
    assert "prompt followed" in printed
    # the scene is kept, so each panel can be rerun with `langtraj simulate`
    scene = read_scenario(out / "scene.tfrecord")
    ids = set(scene.agents.ids[sim_agent_indices(scene)].tolist())
    assert {summary["adversary"], summary["target"]} <= ids
