"""What a simulation is asked to do: how a scene is simulated (`SimConfig`) and which policy drives it
with which prompts and guidance (`SimRequest`, as the command line states it) (docs/simulation.md).

Each option is listed once, as a field: its flag and help for `langtraj simulate` ride in the field's metadata
(`option`), from which the command line's arguments are made (`add_options`) and read back (`from_args`)."""

from __future__ import annotations

import argparse
import math
from collections.abc import Mapping
from dataclasses import MISSING, Field, dataclass, field, fields, is_dataclass
from pathlib import Path
from typing import Any, TypeVar

from langtraj.errors import InputError
from langtraj.rollouts.container import WOSAC_ROLLOUTS
from langtraj.scenario.model import STEP_SECONDS

UNDRIVEN = ("constant_velocity", "log")
"""How sim agents that no policy drives move: by the WOSAC constant-velocity rule from their history
(reads no future), or along their logged future (log replay: flagged, never a valid WOSAC simulation)."""

OPTION = "langtraj.option"
"""The key of a field's metadata that says how the command line states it (`option`)."""


@dataclass(frozen=True)
class Option:
    """How `langtraj simulate` states one field of `SimConfig`, `SimRequest` or `PromptLevers`: its `flag` (None: the
    field is set from Python only, or, for a dataclass-valued field, by its own fields' flags), its `help` (formatted
    with `add_options`' context), further `argparse` keywords (its default is the field's), and, for `SimRequest`,
    whether only a model policy can honour a value other than the default (`model_only`)."""

    flag: str | None = None
    help: str | None = None
    model_only: bool = True
    argparse: Mapping[str, Any] = field(default_factory=dict)

    @property
    def dest(self) -> str:
        """The attribute of the parsed arguments that holds the value."""
        assert self.flag is not None
        return self.argparse.get("dest") or self.flag.lstrip("-").replace("-", "_")


def option(flag: str | None = None, help: str | None = None, *, model_only: bool = True, **argparse: Any) -> dict:
    """Field metadata for an `Option` (`dataclasses.field(metadata=option(...))`)."""
    return {OPTION: Option(flag, help, model_only, argparse)}


def _option(f: Field) -> Option:
    return f.metadata.get(OPTION) or Option()


def _default(f: Field) -> Any:
    assert f.default is not MISSING, f"{f.name} has no plain default"
    return f.default


def _nested(f: Field) -> type | None:
    """The dataclass whose own fields give the flags of `f` (`SimRequest.levers`: `PromptLevers`), else None."""
    return type(f.default) if _option(f).flag is None and is_dataclass(f.default) else None


def add_options(parser: argparse.ArgumentParser, cls: type, **context: str) -> None:
    """One argument of `parser` per field of the dataclass `cls` that has a flag (a dataclass-valued field: one per
    field of its class), in field order, defaulting to the field's default; `context` fills the help texts'
    `{names}`."""
    for f in fields(cls):
        nested = _nested(f)
        if nested is not None:
            add_options(parser, nested, **context)
            continue
        spec = _option(f)
        if spec.flag is None:
            continue
        kwargs = dict(spec.argparse)
        if spec.help is not None:
            kwargs["help"] = spec.help.format(**context)
        default = _default(f)
        kwargs.setdefault("default", list(default) if kwargs.get("action") == "append" else default)
        parser.add_argument(spec.flag, **kwargs)


T = TypeVar("T")


def from_args(cls: type[T], args: argparse.Namespace) -> T:
    """The `cls` (a dataclass whose options `add_options` added to the parser) that parsed `args` state; fields
    without a flag keep their default."""
    values: dict[str, Any] = {}
    for f in fields(cls):  # type: ignore[arg-type]
        nested = _nested(f)
        if nested is not None:
            values[f.name] = from_args(nested, args)
        elif _option(f).flag is not None:
            value = getattr(args, _option(f).dest)
            values[f.name] = tuple(value) if isinstance(value, list) else value
    return cls(**values)


def flag_of(cls: type, name: str) -> str:
    """How the command line names field `name` of `cls` (its flag; the field's name when it has none)."""
    return _option(next(f for f in fields(cls) if f.name == name)).flag or name


def _normalise(obj: Any) -> None:
    """Gives each field of the frozen dataclass `obj` the type its option parses to: a list of a repeatable option
    becomes a tuple, a number of a float option a float, a switch a bool (None stays None)."""
    for f in fields(obj):
        spec, value = _option(f), getattr(obj, f.name)
        if value is None:
            continue
        if isinstance(value, list):
            value = tuple(value)
        elif spec.argparse.get("type") is float:
            value = float(value)
        elif spec.argparse.get("action") in ("store_true", "store_false", argparse.BooleanOptionalAction):
            value = bool(value)
        object.__setattr__(obj, f.name, value)


@dataclass(frozen=True)
class SimConfig:
    """How a scene is simulated: `rollouts` joint rollouts (32 for WOSAC), replanned every `replan_s`
    seconds (a multiple of the 0.1 s step), from random streams fixed by `seed`."""

    rollouts: int = field(
        default=WOSAC_ROLLOUTS, metadata=option("--rollouts", "joint rollouts (default 32, as WOSAC)", type=int)
    )
    replan_s: float = field(
        default=1.0, metadata=option("--replan-s", "seconds between replans (default 1)", type=float)
    )
    seed: int = field(default=0, metadata=option("--seed", type=int))

    def __post_init__(self) -> None:
        if self.rollouts < 1:
            raise InputError(f"rollouts must be at least 1, got {self.rollouts}", where="rollouts")
        steps = self.replan_s / STEP_SECONDS
        if not (steps >= 1 and math.isclose(steps, round(steps), abs_tol=1e-6)) or self.replan_s > 8.0:
            raise InputError(f"replan_s must be a multiple of 0.1 s in [0.1, 8], got {self.replan_s}", where="replan_s")

    @property
    def replan_steps(self) -> int:
        return round(self.replan_s / STEP_SECONDS)


def _lever(name: str, what: str) -> dict:
    return option(
        f"--no-prompt-{name}",
        f"a prompt steers without {what} (on by default; docs/simulation.md, 'Prompts that steer')",
        dest=f"prompt_{name}",
        action="store_false",
    )


@dataclass(frozen=True)
class PromptLevers:
    """How a prompt steers a simulation (docs/simulation.md, 'Prompts that steer'): the model is conditioned on its
    `text`; `guidance` adds terms toward the target the map gives the behaviour read from it; `selection` prefers,
    per prompted agent, the candidates that do what it asks. All three by default; each can be switched off for
    an ablation (`--no-prompt-text`, `--no-prompt-guidance`, `--no-prompt-selection`)."""

    text: bool = field(default=True, metadata=_lever("text", "conditioning the model on the prompt's text"))
    guidance: bool = field(
        default=True,
        metadata=_lever("guidance", "guidance toward the target the map gives the behaviour read from the prompt"),
    )
    selection: bool = field(
        default=True,
        metadata=_lever("selection", "preferring, per prompted agent, the candidates that do what it asks"),
    )

    def names(self) -> list[str]:
        """The levers that are on, by name."""
        return [f.name for f in fields(self) if getattr(self, f.name)]


ALL_LEVERS = PromptLevers()


@dataclass(frozen=True)
class SimRequest:
    """A simulation as the command line states it (track ids, not model slots): one field per option of
    `langtraj simulate`, its flag and help in the field's metadata (`option`). Each policy's `from_request` reads
    the fields it understands and refuses the others; a model policy keeps the request, with its defaults for
    the fields left at None (`sim.policies.resolved`)."""

    policy: str = field(
        default="langtraj",
        metadata=option("--policy", "a registered policy: langtraj (default), {policies}", model_only=False),
    )
    checkpoint: Path | None = field(  # None: the shipped checkpoint
        default=None,
        metadata=option("--checkpoint", "trained checkpoint (default: the shipped one)", model_only=False, type=Path),
    )
    prompts: tuple[str, ...] = field(
        default=(),
        metadata=option("--prompt", 'text naming agents by track id: "@12 yields to @7" (repeatable)', action="append"),
    )
    levers: PromptLevers = field(default=ALL_LEVERS, metadata=option())  # how prompts steer: `PromptLevers`' flags
    adversary: int | None = field(
        default=None, metadata=option("--adversary", "track id driven into --target by collision guidance", type=int)
    )
    target: int | None = field(
        default=None, metadata=option("--target", "track id the adversary collides with", type=int)
    )
    collision_weight: float = field(
        default=1.0,
        metadata=option(
            "--collision-weight", "weight of the collision guidance (default 1)", model_only=False, type=float
        ),
    )
    guidance: tuple[str, ...] = field(  # "NAME=WEIGHT"
        default=(),
        metadata=option(
            "--guidance",
            "extra guidance cost on every driven agent: no_collision, on_road, keep_lane (repeatable)",
            action="append",
            metavar="NAME=WEIGHT",
        ),
    )
    on_road: float | None = field(  # None: the policy's default
        default=None,
        metadata=option(
            "--on-road",
            "weight of the on-road guidance every driven agent gets (default 1, chosen by measurement; 0: off)",
            type=float,
            metavar="W",
        ),
    )
    no_collision: float | None = field(  # None: the policy's default
        default=None,
        metadata=option(
            "--no-collision",
            "weight per agent pair of the no-collision guidance between driven agents (default 1, chosen by "
            "measurement; 0: off; an --adversary and its --target are left out)",
            type=float,
            metavar="W",
        ),
    )
    # The weight keeping the driven agents clear of external ones (an ego under test; None: the policy's default).
    # No flag: `langtraj.env` sets it (docs/testing.md, 'How the other agents react').
    external_clearance: float | None = field(default=None, metadata=option(type=float))
    guided_steps: int | None = field(  # None: the policy's default
        default=None,
        metadata=option(
            "--guided-steps",
            "the on-road and no-collision guidance apply at the last N denoising steps (default: chosen by "
            "measurement, docs/experiments.md; --steps: every step)",
            type=int,
            metavar="N",
        ),
    )
    warm_steps: int | None = field(  # None: every replan starts from fresh noise
        default=None,
        metadata=option(
            "--warm-steps",
            "each replan starts from the plan executed so far, noised to the last N of the --steps denoising "
            "steps (N network calls instead of --steps; docs/simulation.md, 'Warm-started replans'); default: "
            "fresh noise",
            type=int,
            metavar="N",
        ),
    )
    rolling: bool = field(
        default=False,
        metadata=option(
            "--rolling",
            "keep one rolling plan per agent whose noise rises along the future and denoise it once per replan "
            "(a checkpoint trained with model.rolling_group; docs/simulation.md, 'Rolling plans')",
            action="store_true",
        ),
    )
    temperature: float = field(
        default=1.0,
        metadata=option(
            "--temperature",
            "scale the sampler's noise by T in (0, 2] (below 1: nearer the model's most likely future, less "
            "diverse; docs/simulation.md)",
            type=float,
            metavar="T",
        ),
    )
    refresh_map: bool = field(
        default=False,
        metadata=option(
            "--refresh-map",
            "each replan chooses the model's map pieces around where the agents are then (default: the start's "
            "map for every replan; docs/simulation.md, 'The map at each replan')",
            action="store_true",
        ),
    )
    hard_constraints: int | None = field(  # None: the policy's default; 0: off
        default=None,
        metadata=option(
            "--hard-constraints",
            "at the last N denoising steps, project every plan onto the road and out of overlap and refit its "
            "actions (docs/simulation.md, 'Hard constraints'; default: chosen by measurement; 0: off)",
            type=int,
            metavar="N",
        ),
    )
    hold_parked: bool | None = field(  # None: the policy's default
        default=None,
        metadata=option(
            "--hold-parked",
            "agents parked in the log (still through their history, off the travel lanes) stand still unless a "
            "prompt names them (default: chosen by measurement, docs/simulation.md)",
            action=argparse.BooleanOptionalAction,
        ),
    )
    selector: str | None = field(  # `sim.selection.SELECTORS`; None: the policy's default
        default=None,
        metadata=option(
            "--selector",
            "candidate selection: per_agent (default without guidance), min_guidance (default with it), "
            "min_collision (the paper's), min_collision_offroad, first",
        ),
    )
    dense_attention: bool = field(
        default=False,
        metadata=option(
            "--dense-attention",
            "every driven agent attends to every agent and map piece (default: in scenes larger than the model's "
            "training scenes, each attends to a neighbourhood of the size it was trained on; docs/model.md)",
            action="store_true",
        ),
    )
    compile: bool = field(
        default=False,
        metadata=option(
            "--compile",
            "compile the denoiser with torch.compile (the first replan compiles, a minute or so: pays on a GPU, "
            "where a denoising step is bound by launching small kernels; docs/model.md)",
            action="store_true",
        ),
    )
    guidance_scale: float = field(
        default=1.0,
        metadata=option("--guidance-scale", "step size alpha of reconstruction guidance", model_only=False, type=float),
    )
    cfg: float = field(
        default=0.0,
        metadata=option("--cfg", "classifier-free guidance weight w (-1: ignore text)", model_only=False, type=float),
    )
    candidates: int = field(
        default=4,
        metadata=option(
            "--candidates", "candidates sampled per replan (default 4; paper: 64 on a GPU)", model_only=False, type=int
        ),
    )
    steps: int = field(
        default=5, metadata=option("--steps", "DDIM steps per sample (default 5)", model_only=False, type=int)
    )
    max_driven: int | None = field(  # None: the model drives every sim agent
        default=None,
        metadata=option(
            "--max-driven",
            "the model drives only the N most important sim agents (default: every sim agent)",
            type=int,
            metavar="N",
        ),
    )
    undriven: str = field(  # how the others move (`sim.world.UNDRIVEN`); "log" reads the future
        default="constant_velocity",
        metadata=option(
            "--undriven",
            "how sim agents the model does not drive move: constant_velocity (default; reads no future) or log "
            "(replays the logged future: flagged, and refused by langtraj submit)",
            choices=UNDRIVEN,
        ),
    )

    def __post_init__(self) -> None:
        _normalise(self)
        if self.max_driven is not None and self.max_driven < 1:
            raise InputError(f"must be >= 1, got {self.max_driven}", where="--max-driven")
        if self.hard_constraints is not None and self.hard_constraints < 0:
            raise InputError(f"must be >= 0, got {self.hard_constraints}", where="--hard-constraints")
        if self.undriven not in UNDRIVEN:
            raise InputError(f"must be one of {', '.join(UNDRIVEN)}, got {self.undriven!r}", where="--undriven")

    def model_options(self) -> list[str]:
        """The options set to other than their default that only a model policy can honour (prompts, guidance,
        candidate selection, a cap on the agents the model drives, ...), by flag (a lever: the flag that switched it
        off)."""
        named = []
        for f in fields(self):
            value = getattr(self, f.name)
            if not _option(f).model_only or value == _default(f):
                continue
            nested = _nested(f)
            if nested is None:
                named.append(flag_of(SimRequest, f.name))
            else:
                named += [flag_of(nested, g.name) for g in fields(value) if getattr(value, g.name) != _default(g)]
        return named

    @property
    def needs_model(self) -> bool:
        """Whether the request asks for something only a model policy can do (`model_options`)."""
        return bool(self.model_options())
