"""`langtraj experiment realism`: method specs, and a small table of baselines and a model with the
offroad-aware selector and on-road guidance, every agent driven."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from dataset_builders import write_dataset

from langtraj.cli.main import main
from langtraj.errors import InputError
from langtraj.experiments.realism import COLUMNS, FLOW_COLUMNS, Method, by_kind

FREE_TEXT = Path(__file__).parents[1] / "data" / "free_text_prompts.yaml"


def test_method_specs():
    assert Method.parse("cv=constant_velocity").baseline == "constant_velocity"
    model = Method.parse("m=runs/x.ckpt|selector=min_collision_offroad|guidance=on_road:1+no_collision:0.5")
    assert model.selector == "min_collision_offroad" and model.guidance == ("on_road=1", "no_collision=0.5")
    assert not model.defaults and Method.parse("m=runs/x.ckpt|defaults").defaults
    assert not model.dense and Method.parse("m=runs/x.ckpt|dense|defaults").dense
    assert model.guided_steps is None and Method.parse("m=x.ckpt|defaults|guided_steps=2").guided_steps == 2
    assert model.warm_steps is None and Method.parse("m=x.ckpt|warm_steps=2").warm_steps == 2
    assert model.temperature == 1.0 and Method.parse("m=x.ckpt|temperature=0.5").temperature == 0.5
    assert model.project is None and Method.parse("m=x.ckpt|project=2").project == 2
    assert not model.hold_parked and Method.parse("m=x.ckpt|defaults|hold_parked").hold_parked
    assert not model.rolling and Method.parse("m=x.ckpt|defaults|rolling").rolling
    assert model.project_choice and not Method.parse("m=x.ckpt|defaults|project_choice=0").project_choice
    assert model.polish is None and Method.parse("m=x.ckpt|defaults|polish=0").polish == 0
    assert model.polish_steps is None and Method.parse("m=x.ckpt|polish_steps=20").polish_steps == 20
    assert model.constraints(None).polish_steps == 30  # the default's
    assert Method.parse("m=x.ckpt|polish_steps=0").constraints(None).polish_steps is None  # the whole plan
    for bad, message in (
        ("nothing", "expected NAME=SPEC"),
        ("cv=constant_velocity|selector=first", "takes no options"),
        ("m=x.ckpt|speed=3", "expected selector=NAME"),
        ("m=x.ckpt|guidance=goal:1", "'goal' cannot be given here"),
        ("m=x.ckpt|guided_steps=two", "guided_steps must be an integer"),
        ("m=x.ckpt|temperature=cold", "temperature must be a number"),
        ("m=x.ckpt|polish=many", "polish must be an integer"),
        ("m=x.ckpt|polish_steps=2.5", "polish_steps must be an integer"),
    ):
        with pytest.raises(InputError, match=message):
            Method.parse(bad)


def test_merges_and_roundabouts_get_rows_of_their_own():
    per_window = {"m": [{c: float(k) for c in (*COLUMNS, *FLOW_COLUMNS)} | {"min_meta": 0.0} for k in range(4)]}
    kinds = ["onramp", "city", "onramp", "allway"]
    table = by_kind(per_window, kinds, ("onramp", "roundabout"))
    assert list(table) == ["onramp"]  # no roundabout window: no row
    assert table["onramp"]["m"]["meta"] == 1.0 and table["onramp"]["m"]["windows"] == 2  # windows 0 and 2


def test_the_realism_table_scores_every_method(tiny_run, tmp_path, capsys):
    checkpoint, _ = tiny_run
    labels = write_dataset(tmp_path, 4)
    out = tmp_path / "realism.json"
    methods = ["cv=constant_velocity", "still=stationary", "log=log_replay",
               f"model={checkpoint}|selector=min_collision_offroad|guidance=on_road:1",
               f"sim={checkpoint}|defaults"]  # fmt: skip
    args = ["experiment", "realism", "--data", f"toy={labels}:all:2", "--windows", "2", "--candidates", "2",
            "--steps", "2", "--json", str(out)]  # fmt: skip
    assert main([*args, *(x for m in methods for x in ("--method", m))]) == 0
    assert "| model |" in capsys.readouterr().out
    table = json.loads(out.read_text())["toy"]["table"]
    assert set(table) == {"cv", "still", "log", "model", "sim"}
    for row in table.values():
        assert row["windows"] == 2
        assert all(math.isnan(row[c]) or 0.0 <= row[c] <= 1.0 for c in COLUMNS)
    assert table["log"]["meta"] > table["still"]["meta"]  # replaying the log is what the log scores best
    assert table["log"]["speed_ratio"] == pytest.approx(1.0, abs=1e-3) and table["still"]["speed_ratio"] == 0.0
    scenes = json.loads(out.read_text())["toy"]["per_scene"]  # each scene's figures per method (metrics.flow)
    assert all(set(methods) == set(table) for methods in scenes.values())


def test_the_closed_loop_table_takes_rollouts_per_dataset(tiny_run, tmp_path, capsys):
    checkpoint, _ = tiny_run
    labels = write_dataset(tmp_path, 2)
    out = tmp_path / "closed.json"
    args = ["experiment", "closed-loop", "--checkpoint", str(checkpoint), "--data", f"toy={labels}:all:2",
            "--windows", "1", "--candidates", "2", "--steps", "2", "--json", str(out)]  # fmt: skip
    assert main(args) == 0
    assert "2 rollouts" in capsys.readouterr().out
    table = json.loads(out.read_text())["toy"]["table"]
    assert table["log replay"]["windows"] == 1 and 0.0 <= table["LangTraj, text"]["meta"] <= 1.0
    assert main([*args[:5], f"toy={labels}:all:x"]) == 2
    assert "rollouts must be a whole number" in capsys.readouterr().err


def test_the_instruction_following_table_judges_ground_truth_and_counterfactual_prompts(tiny_run, tmp_path, capsys):
    checkpoint, _ = tiny_run
    labels = write_dataset(tmp_path, 3)
    out = tmp_path / "ifr.json"
    args = ["experiment", "instruction-following", "--checkpoint", str(checkpoint), "--data", f"toy={labels}:all",
            "--windows", "1", "--agents", "1", "--counterfactuals", "1", "--rollouts", "2", "--candidates", "2",
            "--steps", "2", "--cfg", "1", "--json", str(out),
            "--free-text", str(FREE_TEXT)]  # fmt: skip
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "| no prompt |" in printed and "| text + guidance |" in printed and "GT-IFR" in printed
    result = json.loads(out.read_text())["toy"]
    table = result["table"]
    assert set(table) - {"default, free text"} == {"no prompt", "text", "guidance", "text + guidance", "default"}
    if "default, free text" in table:  # the prompts of behaviours the hand-written file covers, in its words
        assert 1 <= table["default, free text"]["simulations"] <= result["prompts"]
    prompts = result["prompts"]
    assert prompts >= 1
    assert table["no prompt"]["simulations"] == 1 and table["default"]["simulations"] == prompts
    for condition, judged in result["judgements"].items():
        assert len(judged) == prompts * 2  # every prompt on every rollout
        counterfactual = [j["followed"] for j in judged if not j["ground_truth"]]
        assert counterfactual and table[condition]["report"]["f_ifr"]["judgements"] == len(counterfactual)
        if table[condition]["f_ifr"] is not None:
            assert 0.0 <= table[condition]["f_ifr"] <= 1.0
        row = table[condition]
        assert 0.0 <= row["prompted_collision"] <= 1.0 and row["seconds_per_simulation"] > 0
    assert main([*args[:5], f"toy={labels}:all", "--conditions", "text,default"]) == 2  # 'no prompt' is the base
    assert "--conditions" in capsys.readouterr().err
    assert main([*args[:5], f"toy={labels}:all", "--cfg", "-2"]) == 2
    assert "--cfg" in capsys.readouterr().err
