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
    assert set(summary["runs"]["prompt"]["prompted_ids"]) == {summary["adversary"], summary["target"]}
    # the scene is kept, so each panel can be rerun with `langtraj simulate`
    scene = read_scenario(out / "scene.tfrecord")
    ids = set(scene.agents.ids[sim_agent_indices(scene)].tolist())
    assert {summary["adversary"], summary["target"]} <= ids
