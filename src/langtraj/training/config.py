"""Training configuration: model, data, optimisation and hardware, read from YAML presets in `configs/`.

A YAML file may name another with `extends: other.yaml` (relative to itself); its keys then override
the other's, section by section. Hardware is configuration only: `accelerator`, `devices`,
`num_nodes` and `strategy` (e.g. ddp) go straight to the Lightning Trainer, so the same command runs
on a laptop CPU, one GPU or several nodes (launched with torchrun or a cluster scheduler).

See docs/model.md.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from langtraj.errors import InputError
from langtraj.model.config import ModelConfig, SampleConfig
from langtraj.scenario import FUTURE_STEPS
from langtraj.settings import dataclass_kwargs, read_yaml, require


@dataclass(frozen=True)
class OptimConfig:
    """AdamW with linear warm-up then cosine decay to `min_lr_ratio` of the peak at `max_steps`."""

    lr: float = 3e-4
    weight_decay: float = 0.01
    warmup_steps: int = 200
    min_lr_ratio: float = 0.05
    grad_clip: float = 1.0

    def __post_init__(self) -> None:
        require(self.lr > 0, "optim.lr", f"must be > 0, got {self.lr}")
        require(self.warmup_steps >= 0, "optim.warmup_steps", f"must be >= 0, got {self.warmup_steps}")
        require(0 <= self.min_lr_ratio <= 1, "optim.min_lr_ratio", f"must be in [0, 1], got {self.min_lr_ratio}")
        require(self.grad_clip >= 0, "optim.grad_clip", f"must be >= 0, got {self.grad_clip}")


@dataclass(frozen=True)
class ValConfig:
    """What validation measures: minADE over `num_samples` samples (with and without text in stage 2)
    on up to `max_batches` batches, and WOSAC metrics on `wosac_scenes` scenes (0: off)."""

    num_samples: int = 6
    sample_steps: int = 10  # DDIM steps used when sampling for validation
    max_batches: int = 4
    wosac_scenes: int = 2
    wosac_rollouts: int = 32

    def __post_init__(self) -> None:
        for name in ("num_samples", "sample_steps", "max_batches", "wosac_rollouts"):
            require(getattr(self, name) >= 1, f"val.{name}", f"must be >= 1, got {getattr(self, name)}")
        require(self.wosac_scenes >= 0, "val.wosac_scenes", f"must be >= 0, got {self.wosac_scenes}")


COMPILE_MODES = ("default", "reduce-overhead", "max-autotune", "max-autotune-no-cudagraphs")
"""`torch.compile` modes a preset may name (`TrainConfig.compile_mode`)."""

OBJECTIVES = ("denoising", "closed_loop")
"""What a stage minimises: the denoising loss at a random noise level (stages 1 and 2, and distillation
to fewer steps), or Algorithm 1's closed-loop loss (`training.closed_loop`)."""


@dataclass(frozen=True)
class ClosedLoopConfig:
    """Algorithm 1's settings, defaults from the appendix 'Closed-loop Training Details': `iterations`
    replans of `replan_actions` executed actions each (4 x 2 x 0.5 s over the 8 s of ground truth with a
    4-s horizon), `candidates` one-step-denoised samples per replan (M), noise levels tau ~ U(1, K x
    `noise_ratio`) (gamma), teacher forcing in `teacher_forcing` of the samples for `forced_agents` of
    their agents, and the non-collision loss weighted `collision_weight`. `denoising_weight` adds the
    usual denoising loss of the same batch (every noise level; Algorithm 1 trains only tau <= K gamma,
    while sampling starts from pure noise): not in the paper, off by default."""

    iterations: int = 4
    replan_actions: int = 2
    candidates: int = 8
    noise_ratio: float = 0.6
    teacher_forcing: float = 0.5
    forced_agents: float = 0.7
    collision_weight: float = 0.1
    denoising_weight: float = 0.0  # not in the paper: the plain denoising loss beside it, at every noise level

    def __post_init__(self) -> None:
        for name in ("iterations", "replan_actions", "candidates"):
            require(getattr(self, name) >= 1, f"closed_loop.{name}", f"must be >= 1, got {getattr(self, name)}")
        require(0 < self.noise_ratio <= 1, "closed_loop.noise_ratio", f"must be in (0, 1], got {self.noise_ratio}")
        for name in ("teacher_forcing", "forced_agents"):
            value = getattr(self, name)
            require(0 <= value <= 1, f"closed_loop.{name}", f"must be in [0, 1], got {value}")
        for name in ("collision_weight", "denoising_weight"):
            value = getattr(self, name)
            require(value >= 0, f"closed_loop.{name}", f"must be >= 0, got {value}")

    def check(self, num_actions: int, logged_actions: int) -> None:
        """InputError unless the last replan's horizon (`num_actions` model actions) ends within the
        `logged_actions` actions of ground truth a sample holds."""
        need = (self.iterations - 1) * self.replan_actions + num_actions
        require(
            need <= logged_actions,
            "closed_loop",
            f"{self.iterations} replans of {self.replan_actions} actions with a {num_actions}-action horizon need "
            f"{need} logged actions; samples hold {logged_actions}",
        )


@dataclass(frozen=True)
class PerturbationConfig:
    """Recovery training (ChauffeurNet's perturbations; not in the paper): each moving agent (at least
    `min_speed` m/s), with probability `probability`, has its observed past moved rigidly sideways by up
    to `lateral_m` and turned by up to `heading_rad` about its current position, while its target future
    stays the logged one; so the model sees agents off their lane and learns to steer back, which logged
    traffic, always on its lane, never shows (docs/model.md, 'Recovery training'). Off by default."""

    probability: float = 0.0
    lateral_m: float = 1.0
    heading_rad: float = 0.1
    min_speed: float = 3.0

    def __post_init__(self) -> None:
        require(0 <= self.probability <= 1, "perturbation.probability", f"must be in [0, 1], got {self.probability}")
        for name in ("lateral_m", "heading_rad", "min_speed"):
            value = getattr(self, name)
            require(value >= 0, f"perturbation.{name}", f"must be >= 0, got {value}")


@dataclass(frozen=True)
class PenaltyConfig:
    """Map- and contact-aware training (not in the paper): penalties on the trajectory the predicted clean
    actions produce, beside the denoising loss (`training/penalties.py`, docs/model.md, 'Scene penalties').
    `road_weight` weighs leaving the road further than the logged future does (m^2 per vehicle step; the
    log may come within `road_margin` m of an edge), `contact_weight` the disk overlap between agents
    (guidance's no-collision cost, per agent). Both 0: off, the default."""

    road_weight: float = 0.0
    contact_weight: float = 0.0
    road_margin: float = 0.5

    def __post_init__(self) -> None:
        for name in ("road_weight", "contact_weight", "road_margin"):
            value = getattr(self, name)
            require(math.isfinite(value) and value >= 0, f"penalties.{name}", f"must be finite and >= 0, got {value}")

    @property
    def active(self) -> bool:
        return self.road_weight > 0 or self.contact_weight > 0


@dataclass(frozen=True)
class TrainConfig:
    """One training stage. Stage 1 learns without text; stage 2 adds text (and LoRA), starting from
    `init_from` (a stage-1 checkpoint) when given."""

    name: str = "tiny"
    stage: int = 1
    model: ModelConfig = field(default_factory=ModelConfig)
    data: SampleConfig = field(default_factory=SampleConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    val: ValConfig = field(default_factory=ValConfig)
    batch_size: int = 16
    max_steps: int = 2000
    val_every_steps: int = 500
    checkpoint_every_steps: int = 100
    keep_every_steps: int | None = None
    """Also keep a checkpoint every this many steps in RUN_DIR/checkpoints/kept/ (never deleted): milestones
    for a scaling table or a learning curve. None: only the latest checkpoints are kept."""
    text_loss_weight: float = 1.0  # stage 2: loss weight of the agents that carry a sentence
    num_workers: int = 0
    seed: int = 0
    init_from: str | None = None
    objective: str = "denoising"
    closed_loop: ClosedLoopConfig = field(default_factory=ClosedLoopConfig)
    perturbation: PerturbationConfig = field(default_factory=PerturbationConfig)
    penalties: PenaltyConfig = field(default_factory=PenaltyConfig)
    accelerator: str = "auto"
    devices: int | str = "auto"
    num_nodes: int = 1
    strategy: str = "auto"
    precision: str = "32-true"
    compile: bool = False
    """Compile the training step's network part with `torch.compile` (`LangTraj.compile_steps`): the forward
    and backward passes become a few fused kernels instead of some 15,000 small operations, what a GPU step
    is bound by (docs/model.md, 'Fewer, bigger kernels'). Same loss to float rounding; the first steps
    compile (a minute or so)."""
    compile_mode: str = "default"
    """`torch.compile`'s mode: "default", "reduce-overhead" (CUDA graphs: shapes must stay fixed),
    "max-autotune" or "max-autotune-no-cudagraphs"."""

    def __post_init__(self) -> None:
        for name in ("batch_size", "max_steps", "val_every_steps", "checkpoint_every_steps", "num_nodes"):
            require(getattr(self, name) >= 1, name, f"must be >= 1, got {getattr(self, name)}")
        require(
            self.model.history_steps == self.data.history_steps,
            "data.history_steps",
            f"{self.data.history_steps} steps of history in the samples, the model reads {self.model.history_steps}"
            " (model.history_steps): they must agree",
        )
        require(
            self.model.dynamics == self.data.dynamics,
            "data.dynamics",
            f"samples fit target actions with {self.data.dynamics!r}, the model integrates {self.model.dynamics!r}"
            " (model.dynamics): they must agree",
        )
        require(
            self.keep_every_steps is None or self.keep_every_steps >= 1,
            "keep_every_steps",
            f"must be >= 1, got {self.keep_every_steps}",
        )
        require(
            self.compile_mode in COMPILE_MODES,
            "compile_mode",
            f"must be one of {', '.join(COMPILE_MODES)}, got {self.compile_mode!r}",
        )
        require(self.num_workers >= 0, "num_workers", f"must be >= 0, got {self.num_workers}")
        require(self.text_loss_weight >= 0, "text_loss_weight", f"must be >= 0, got {self.text_loss_weight}")
        require(
            self.objective in OBJECTIVES, "objective", f"must be one of {', '.join(OBJECTIVES)}, got {self.objective!r}"
        )
        require(
            self.val.sample_steps <= self.model.diffusion_steps,
            "val.sample_steps",
            f"{self.val.sample_steps} sampling steps for a {self.model.diffusion_steps}-step model",
        )
        horizon = self.model.num_actions * 5  # 0.5-s actions at 10 Hz
        require(
            not self.val.wosac_scenes or horizon >= FUTURE_STEPS,
            "val.wosac_scenes",
            f"WOSAC validation scores 8 s; this model plans {horizon / 10:g} s (set wosac_scenes: 0)",
        )
        if self.objective == "closed_loop":
            self.closed_loop.check(self.model.num_actions, self.data.future_steps // 5)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any], where: str = "config") -> TrainConfig:
        data = dataclass_kwargs(cls, data, where)
        try:
            sections = {
                "model": ModelConfig.from_dict(data.pop("model", {})),
                "data": SampleConfig.from_dict(data.pop("data", {})),
                "optim": OptimConfig(**dataclass_kwargs(OptimConfig, data.pop("optim", {}), "optim")),
                "val": ValConfig(**dataclass_kwargs(ValConfig, data.pop("val", {}), "val")),
                "closed_loop": ClosedLoopConfig(
                    **dataclass_kwargs(ClosedLoopConfig, data.pop("closed_loop", {}), "closed_loop")
                ),
                "perturbation": PerturbationConfig(
                    **dataclass_kwargs(PerturbationConfig, data.pop("perturbation", {}), "perturbation")
                ),
                "penalties": PenaltyConfig(**dataclass_kwargs(PenaltyConfig, data.pop("penalties", {}), "penalties")),
            }
            config = cls(**sections, **data)
        except TypeError as exc:
            raise InputError(str(exc), where=where) from None
        except InputError as exc:
            raise exc.located(path=where) from None
        if config.stage not in (1, 2):
            raise InputError(f"stage must be 1 or 2, got {config.stage}", where=where)
        if config.stage == 2 and not config.model.use_text:
            raise InputError("stage 2 trains with text: model.use_text must be true", where=where)
        return config


def load_config(path: str | Path) -> TrainConfig:
    """The training configuration of a YAML preset (see `configs/`)."""
    return TrainConfig.from_dict(read_yaml(Path(path)), where=str(path))
