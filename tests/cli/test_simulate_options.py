"""`langtraj simulate`'s simulation options are listed once: as fields of `SimRequest` and `SimConfig`, each with its
flag and help in the field's metadata (`sim.config.option`). The command line's arguments are made from the fields
and read back into the same request; a model policy keeps that request (`LangTrajPolicy.request`)."""

from __future__ import annotations

import argparse
from dataclasses import fields, replace
from pathlib import Path

import pytest

from langtraj.cli.main import build_parser
from langtraj.errors import InputError
from langtraj.sim.config import ALL_LEVERS, PromptLevers, SimConfig, SimRequest, flag_of, from_args
from langtraj.sim.policies import POLICIES

FLAGS = ["--out", "--index", "--policy", "--checkpoint", "--prompt", "--no-prompt-text", "--no-prompt-guidance",
         "--no-prompt-selection", "--adversary", "--target", "--collision-weight", "--guidance", "--on-road",
         "--no-collision", "--guided-steps", "--warm-steps", "--rolling", "--temperature", "--refresh-map",
         "--hard-constraints", "--hold-parked", "--no-hold-parked", "--selector", "--dense-attention", "--compile",
         "--guidance-scale", "--cfg", "--rollouts", "--candidates", "--steps", "--replan-s", "--max-driven",
         "--undriven", "--seed", "--no-video"]  # fmt: skip
"""The flags of `langtraj simulate` (as before its options moved into the fields, issue 46)."""

SET_BY_FLAGS = {
    "policy": (["--policy", "guidance_baseline"], "guidance_baseline"),
    "checkpoint": (["--checkpoint", "m.ckpt"], Path("m.ckpt")),
    "prompts": (["--prompt", "@1 stops", "--prompt", "@2 turns left"], ("@1 stops", "@2 turns left")),
    "levers": (["--no-prompt-text", "--no-prompt-selection"], PromptLevers(text=False, selection=False)),
    "adversary": (["--adversary", "7"], 7),
    "target": (["--target", "9"], 9),
    "collision_weight": (["--collision-weight", "2.5"], 2.5),
    "guidance": (["--guidance", "on_road=2", "--guidance", "keep_lane=1"], ("on_road=2", "keep_lane=1")),
    "on_road": (["--on-road", "0.5"], 0.5),
    "no_collision": (["--no-collision", "0"], 0.0),
    "guided_steps": (["--guided-steps", "2"], 2),
    "warm_steps": (["--warm-steps", "3"], 3),
    "rolling": (["--rolling"], True),
    "temperature": (["--temperature", "0.7"], 0.7),
    "refresh_map": (["--refresh-map"], True),
    "hard_constraints": (["--hard-constraints", "0"], 0),
    "hold_parked": (["--no-hold-parked"], False),
    "selector": (["--selector", "first"], "first"),
    "dense_attention": (["--dense-attention"], True),
    "compile": (["--compile"], True),
    "guidance_scale": (["--guidance-scale", "3"], 3.0),
    "cfg": (["--cfg", "-1"], -1.0),
    "candidates": (["--candidates", "8"], 8),
    "steps": (["--steps", "4"], 4),
    "max_driven": (["--max-driven", "6"], 6),
    "undriven": (["--undriven", "log"], "log"),
}
"""For each field of `SimRequest`: arguments that set it to other than its default, and the value they give."""
PYTHON_ONLY = {"external_clearance"}
"""Fields no flag sets (the env's, docs/testing.md)."""


def _parse(*argv: str) -> argparse.Namespace:
    return build_parser().parse_args(["simulate", "scene.tfrecord", "--out", "out", *argv])


def _flags() -> list[str]:
    subparsers = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    simulate = subparsers.choices["simulate"]
    return [flag for action in simulate._actions for flag in action.option_strings if flag.startswith("--")]


def test_the_command_line_has_the_flags_it_had():
    assert sorted(_flags()) == sorted([*FLAGS, "--help"])


def test_every_field_has_one_flag_that_the_command_line_offers():
    assert set(SET_BY_FLAGS) | PYTHON_ONLY == {f.name for f in fields(SimRequest)}  # a new field: give it a flag
    offered = set(_flags())
    for name in set(SET_BY_FLAGS) - {"levers"}:
        assert flag_of(SimRequest, name) in offered, name
    assert {flag_of(PromptLevers, f.name) for f in fields(PromptLevers)} <= offered
    assert {flag_of(SimConfig, f.name) for f in fields(SimConfig)} <= offered


def test_the_defaults_round_trip_to_the_default_request_and_config():
    args = _parse()
    assert from_args(SimRequest, args) == SimRequest()
    assert from_args(SimConfig, args) == SimConfig()


@pytest.mark.parametrize("name", sorted(SET_BY_FLAGS))
def test_each_option_round_trips_from_its_flag_to_its_field(name):
    argv, value = SET_BY_FLAGS[name]
    assert value != getattr(SimRequest(), name)  # a value other than the default, so the test can fail
    request = from_args(SimRequest, _parse(*argv))
    assert request == replace(SimRequest(), **{name: value})
    assert type(getattr(request, name)) is type(value)


def test_every_option_at_once_round_trips_and_the_config_too():
    argv = [arg for args, _ in SET_BY_FLAGS.values() for arg in args]
    args = _parse(*argv, "--rollouts", "3", "--replan-s", "2", "--seed", "5")
    assert from_args(SimRequest, args) == SimRequest(**{name: value for name, (_, value) in SET_BY_FLAGS.items()})
    assert from_args(SimConfig, args) == SimConfig(rollouts=3, replan_s=2.0, seed=5)


def test_a_model_free_policy_names_each_model_option_it_was_given():
    """`needs_model` comes from the fields: every option but the policy, the checkpoint, the sample sizes and the
    guidance weights asks for a model policy, and the refusal names its flag."""
    any_policy = {"policy", "checkpoint", "collision_weight", "guidance_scale", "cfg", "candidates", "steps"}
    assert not SimRequest(**{n: SET_BY_FLAGS[n][1] for n in any_policy}).needs_model
    for name in set(SET_BY_FLAGS) - any_policy:
        request = SimRequest(**{name: SET_BY_FLAGS[name][1]})
        assert request.needs_model, name
        flags = request.model_options()
        assert flags == (
            ["--no-prompt-text", "--no-prompt-selection"] if name == "levers" else [flag_of(SimRequest, name)]
        )
        with pytest.raises(InputError, match=f"{flags[-1]} needs? a model policy"):
            POLICIES.get("constant_velocity").from_request(None, request)  # type: ignore[arg-type]
    assert SimRequest(external_clearance=5.0).model_options() == ["external_clearance"]


def test_values_take_the_type_their_flag_parses_to():
    request = SimRequest(prompts=["@1 stops"], on_road=1, temperature=1, rolling=1, hold_parked=0)  # type: ignore[arg-type]
    assert request.prompts == ("@1 stops",) and request.on_road == 1.0 and isinstance(request.on_road, float)
    assert request.rolling is True and request.hold_parked is False and isinstance(request.temperature, float)
    assert not SimRequest(prompts=[], levers=ALL_LEVERS).needs_model  # type: ignore[arg-type]
