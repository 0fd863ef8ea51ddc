"""`langtraj demo` end to end on a tiny checkpoint: a synthesized scene simulated three ways, side by side."""

from __future__ import annotations

import json
from types import SimpleNamespace

import imageio.v3 as iio
import pytest

from langtraj.cli.main import main
from langtraj.experiments import demo
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.counterfactual import make_alternative
from langtraj.interdrive.targets import TargetUnavailable
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.scenario.io import read_scenario


# Slow (1 min); `pytest -m slow`. CI runs `langtraj demo` itself (.ci/run) and checks what it writes.
@pytest.mark.slow
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


def test_counterfactuals_the_map_gives_a_target_come_first(tiny_run, monkeypatch):
    """A behaviour the map gives no target for (a lane change with no lane beside to change into) loses the
    guidance toward it, so the demo asks for it only when nothing with a target is left."""
    _, scenes = tiny_run
    scenario = read_scenario(scenes)
    track = int(scenario.agents.ids[0])
    lane_change, stop, pull_over = (
        make_alternative(b, track, frozenset())
        for b in (Behaviour.LANE_CHANGE_RIGHT, Behaviour.STOP, Behaviour.PULL_OVER)
    )
    monkeypatch.setattr(demo, "feasible_alternatives", lambda *a, **k: (pull_over, lane_change, stop))
    monkeypatch.setattr(demo, "rollout_facts", lambda *a: [])  # no unconditioned rollout does any of them
    monkeypatch.setattr(demo, "derive_target", lambda *a, **k: object())
    assert demo.choose_counterfactual(scenario, track, -1, None)[0] is lane_change  # COUNTERFACTUAL_ORDER decides

    def no_lane_change(scenario, track_id, behaviour, index, *, other_id=None):
        if behaviour is Behaviour.LANE_CHANGE_RIGHT:
            raise TargetUnavailable(track_id, behaviour, "infeasible", "no lane on its right along its road")
        return object()

    monkeypatch.setattr(demo, "derive_target", no_lane_change)
    assert demo.choose_counterfactual(scenario, track, -1, None)[0] is stop
    monkeypatch.setattr(demo, "feasible_alternatives", lambda *a, **k: (lane_change, pull_over))
    assert demo.choose_counterfactual(scenario, track, -1, None)[0] is pull_over  # unlisted, but has a target


def test_each_panel_marks_its_target_and_the_unconditioned_one_the_prompts():
    stop = {"track_id": 7, "behaviour": "stop", "path": [[0.0, 0.0], [2.0, 0.0], [4.0, 0.0]], "goal": [3.0, 0.0],
            "stop": True, "conflict": None}  # fmt: skip
    turn = {**stop, "behaviour": "turn_left", "goal": [4.0, 0.0], "stop": False}
    results = {
        "unconditioned": SimpleNamespace(report={"map_pieces": 3}),
        "prompt": SimpleNamespace(report={"prompt": {"read": [], "targets": [stop], "steering": []}}),
        "safety-critical": SimpleNamespace(report={"prompt": {"read": [], "targets": [turn], "steering": []}}),
    }
    panels = demo.demo_panels(results, "@7 comes to a stop", 4, 7, (7, 4))
    assert [p.result for p in panels] == list(results.values())
    assert [[m.kind for m in p.marks] for p in panels] == [["path", "stop"], ["path", "stop"], ["path", "goal"]]
    assert panels[0].marks == panels[1].marks and "where the prompt takes @7" in panels[0].caption
    assert panels[0].highlight == () and panels[1].highlight == panels[2].highlight == (7, 4)
    results["prompt"] = SimpleNamespace(report={"prompt": {"read": [], "targets": [], "steering": []}})
    assert demo.demo_panels(results, "@7 comes to a stop", 4, 7, (7, 4))[0].caption == "unconditioned"
