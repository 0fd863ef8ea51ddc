"""What a simulation is asked to do: how a scene is simulated (`SimConfig`) and which policy drives it
with which prompts and guidance (`SimRequest`, as the command line states it) (docs/simulation.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from langtraj.errors import InputError
from langtraj.rollouts.container import WOSAC_ROLLOUTS
from langtraj.scenario.model import STEP_SECONDS

UNDRIVEN = ("constant_velocity", "log")
"""How sim agents that no policy drives move: by the WOSAC constant-velocity rule from their history
(reads no future), or along their logged future (log replay: flagged, never a valid WOSAC simulation)."""


@dataclass(frozen=True)
class SimConfig:
    """How a scene is simulated: `rollouts` joint rollouts (32 for WOSAC), replanned every `replan_s`
    seconds (a multiple of the 0.1 s step), from random streams fixed by `seed`."""

    rollouts: int = WOSAC_ROLLOUTS
    replan_s: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        if self.rollouts < 1:
            raise InputError(f"rollouts must be at least 1, got {self.rollouts}", where="rollouts")
        steps = self.replan_s / STEP_SECONDS
        if not (steps >= 1 and math.isclose(steps, round(steps), abs_tol=1e-6)) or self.replan_s > 8.0:
            raise InputError(f"replan_s must be a multiple of 0.1 s in [0.1, 8], got {self.replan_s}", where="replan_s")

    @property
    def replan_steps(self) -> int:
        return round(self.replan_s / STEP_SECONDS)


@dataclass(frozen=True)
class PromptLevers:
    """How a prompt steers a simulation (docs/simulation.md, 'Prompts that steer'): the model is conditioned on its
    `text`; `guidance` adds terms toward the target the map gives the behaviour read from it; `selection` prefers,
    per prompted agent, the candidates that do what it asks. All three by default; each can be switched off for
    an ablation."""

    text: bool = True
    guidance: bool = True
    selection: bool = True

    def names(self) -> list[str]:
        """The levers that are on, by name."""
        return [name for name in ("text", "guidance", "selection") if getattr(self, name)]


ALL_LEVERS = PromptLevers()


@dataclass(frozen=True)
class SimRequest:
    """A simulation as the command line states it (track ids, not model slots). Each policy's
    `from_request` reads the fields it understands and refuses the others."""

    policy: str = "langtraj"
    checkpoint: Path | None = None  # None: the shipped checkpoint
    prompts: tuple[str, ...] = ()
    adversary: int | None = None
    target: int | None = None
    collision_weight: float = 1.0
    guidance: tuple[str, ...] = ()  # "NAME=WEIGHT"
    guidance_scale: float = 1.0
    cfg: float = 0.0
    candidates: int = 4
    steps: int = 5
    max_driven: int | None = None  # the model drives the N most important sim agents; None: every one
    undriven: str = "constant_velocity"  # how the others move (`sim.world.UNDRIVEN`); "log" reads the future
    selector: str | None = None  # candidate selection (`sim.selection.SELECTORS`); None: the policy's default
    on_road: float | None = None  # weight of the on-road guidance on every driven agent; None: the policy's default
    no_collision: float | None = None  # weight per pair of the no-collision guidance; None: the policy's default
    dense_attention: bool = False  # every agent attends to every token, however large the scene (slower)
    guided_steps: int | None = None  # the last N denoising steps get on-road / no-collision guidance; None: default
    warm_steps: int | None = None  # replans start from the executed plan, noised to the last N steps; None: fresh
    rolling: bool = False  # keep one rolling plan per agent, one network call per replan (a rolling checkpoint)
    temperature: float = 1.0  # the sampler's noise is drawn this many times N(0, I)'s standard deviation
    refresh_map: bool = False  # each replan chooses the map around the agents' positions then (else: the start's)
    levers: PromptLevers = ALL_LEVERS  # how prompts steer (text, guidance toward targets, adherence-first selection)
    external_clearance: float | None = None  # weight keeping the driven agents clear of external ones; None: default
    hard_constraints: int | None = (
        None  # project onto the road and apart at the last N denoising steps; None: default, 0: off
    )
    hold_parked: bool | None = None  # agents parked in the log stand still unless prompted; None: the default
    compile: bool = False  # compile the denoiser (torch.compile; pays on a GPU, docs/model.md 'Fewer, bigger kernels')

    def __post_init__(self) -> None:
        if self.max_driven is not None and self.max_driven < 1:
            raise InputError(f"must be >= 1, got {self.max_driven}", where="--max-driven")
        if self.hard_constraints is not None and self.hard_constraints < 0:
            raise InputError(f"must be >= 0, got {self.hard_constraints}", where="--hard-constraints")
        if self.undriven not in UNDRIVEN:
            raise InputError(f"must be one of {', '.join(UNDRIVEN)}, got {self.undriven!r}", where="--undriven")

    @property
    def needs_model(self) -> bool:
        """Whether the request asks for something only a model policy can do (prompts, guidance, candidate
        selection, a cap on the agents the model drives)."""
        return bool(
            self.prompts
            or self.adversary is not None
            or self.target is not None
            or self.guidance
            or self.max_driven is not None
            or self.undriven != "constant_velocity"
            or self.selector is not None
            or self.on_road is not None
            or self.no_collision is not None
            or self.dense_attention
            or self.guided_steps is not None
            or self.warm_steps is not None
            or self.rolling
            or self.temperature != 1.0
            or self.refresh_map
            or self.levers != ALL_LEVERS
            or self.external_clearance is not None
            or self.hard_constraints is not None
            or self.hold_parked is not None
            or self.compile
        )
