"""The model's configuration: what shapes the network (`ModelConfig`) and what one scene sample holds
(`SampleConfig`), as documented dataclasses saved in every checkpoint (docs/model.md)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.model.text_encoder import TextEncoderConfig
from langtraj.scenario import FUTURE_STEPS, HISTORY_STEPS
from langtraj.settings import dataclass_kwargs


@dataclass(frozen=True)
class ModelConfig:
    """Everything that shapes the network; saved in every checkpoint so a model rebuilds exactly.

    The paper's sizes are in `configs/base.yaml`; `configs/tiny.yaml` trains on a laptop CPU.
    """

    hidden_dim: int = 128  # width of every token
    num_heads: int = 4
    encoder_layers: int = 2  # map self-attention + agent attention rounds in the scene encoder
    denoiser_blocks: int = 3  # (agent-agent, scene, text) attention triples in the denoiser
    dropout: float = 0.1
    history_steps: int = HISTORY_STEPS  # history length the encoder reads (10 Hz, ending at the current step)
    num_actions: int = 16  # 0.5 s actions: 16 cover 8 s
    dynamics: str = "unicycle"
    vehicle_max_curvature: float = 0.25  # 1/m (a 4 m turn radius): vehicles cannot turn on the spot
    turn_radius_per_length: float = 0.8
    """A vehicle of length L (m) turns no tighter than a radius of this times L, where that is wider than
    `vehicle_max_curvature`'s: a 12 m bus 9.6 m (a city bus's kerb-to-kerb circle is about 21 m), a car the 4 m of
    the flat bound. Without it a long vehicle pivots like a car and its box swings off the road (issue 45).
    0: the flat bound alone (docs/model.md, 'Dynamics')."""
    action_scale: tuple[float, float] = (4.0, 0.5)  # m/s^2 and rad/s that map to 1 in the network's units
    diffusion_steps: int = 100  # K (paper: 100 for pretraining)
    map_attention_radius: float = 50.0  # map polylines attend to polylines within this distance (m)
    text: TextEncoderConfig = field(default_factory=TextEncoderConfig)
    use_text: bool = True  # build the language branch (stage 2); stage 1 can skip it
    lane_inputs: bool = False
    """Each agent token also reads its history's lateral offset and heading error to the nearest lane of its
    map pieces (`scene_encoder.lane_relative_history`; docs/model.md, 'Lane-relative inputs'). Off: the paper's
    inputs, and checkpoints trained before it."""
    rolling_group: int = 0
    """Actions a rolling plan moves on by at each replan (`model.rolling`): the denoiser also reads each action's own
    noise level, and training draws levels that rise along the future for `rolling_fraction` of its scenes. 0: one
    noise level per sample, the paper's denoiser (docs/model.md, 'Rolling plans')."""
    rolling_fraction: float = 0.5
    gradient_checkpointing: bool = False
    """Training only: recompute each attention block in backward instead of keeping its activations
    (docs/model.md, 'Training memory'); the weights and every output stay the same."""

    def vehicle_curvature(self, length: Tensor) -> Tensor:
        """The tightest turn (1/m) of vehicles of `length` [...] (m): `vehicle_max_curvature`, and no tighter than a
        radius of `turn_radius_per_length` x the length. The one definition the model's agents and the env's ego
        share."""
        flat = torch.full_like(length, self.vehicle_max_curvature, dtype=torch.float32)
        if self.turn_radius_per_length <= 0:
            return flat
        return torch.minimum(flat, 1.0 / (self.turn_radius_per_length * length.to(flat)).clamp(min=1e-3))

    def __post_init__(self) -> None:
        for name in ("hidden_dim", "num_heads", "num_actions", "diffusion_steps", "history_steps"):
            if getattr(self, name) < 1:
                raise InputError(f"must be >= 1, got {getattr(self, name)}", where=f"model.{name}")
        for name in ("encoder_layers", "denoiser_blocks"):
            if getattr(self, name) < 0:
                raise InputError(f"must be >= 0, got {getattr(self, name)}", where=f"model.{name}")
        if self.hidden_dim % self.num_heads:
            raise InputError(
                f"hidden_dim {self.hidden_dim} is not a multiple of num_heads {self.num_heads}", where="model"
            )
        if not (math.isfinite(self.turn_radius_per_length) and self.turn_radius_per_length >= 0):
            raise InputError(
                f"must be finite and >= 0, got {self.turn_radius_per_length}", where="model.turn_radius_per_length"
            )
        if not 0.0 <= self.dropout < 1.0:
            raise InputError(f"must be in [0, 1), got {self.dropout}", where="model.dropout")
        if len(self.action_scale) != 2:
            raise InputError(f"expected two values, got {list(self.action_scale)}", where="model.action_scale")
        if self.rolling_group < 0 or (self.rolling_group and self.num_actions % self.rolling_group):
            raise InputError(
                f"must be 0 or divide the {self.num_actions} actions, got {self.rolling_group}",
                where="model.rolling_group",
            )
        if not 0.0 <= self.rolling_fraction <= 1.0:
            raise InputError(f"must be in [0, 1], got {self.rolling_fraction}", where="model.rolling_fraction")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any] | None, where: str = "model") -> ModelConfig:
        data = dataclass_kwargs(cls, data, where)
        try:
            text = TextEncoderConfig(**dataclass_kwargs(TextEncoderConfig, data.pop("text", {}), f"{where}.text"))
        except TypeError as exc:
            raise InputError(str(exc), where=f"{where}.text") from None
        if "action_scale" in data:
            data["action_scale"] = tuple(data["action_scale"])
        return cls(text=text, **data)


MAP_SELECTIONS = ("agents", "origin")
"""How a sample's map pieces are chosen (`model.features.map_polylines`): around every agent and the road
ahead of it, or nearest the scene origin (how checkpoints trained before map coverage saw the map)."""


@dataclass(frozen=True)
class SampleConfig:
    """What a scene sample holds (docs/model.md, 'Inputs') and how training augments it.

    Sizes: `max_agents` agents, `max_polylines` map polylines of `points_per_polyline` points within
    `map_radius` m of the map's anchors, `history_steps` steps ending at the current one, `future_steps`
    after it. `map_selection` "agents" covers every agent's surroundings and the road ahead of it (the
    greater of `map_ahead_min` m and `map_ahead_s` seconds at its current speed); "origin" keeps the
    pieces nearest the scene origin (checkpoints from before map coverage). Simulation scales
    `max_polylines` with the number of agents it drives (docs/model.md, 'Inputs'). A feature store also
    keeps each sample's target actions, fitted by `dynamics`' inverse (`model.targets`).
    `text` False is stage 1 (no text at all). The remaining fields are training-time choices that the
    features themselves never read: probabilities per sample (dropouts), a share of a scene's labelled
    agents (`heuristic_label_fraction`) and a share of each batch (`interaction_fraction`); they live here
    so that one checkpoint records everything its samples were built with.
    """

    max_agents: int = 32
    max_polylines: int = 96
    points_per_polyline: int = 20
    history_steps: int = HISTORY_STEPS
    future_steps: int = FUTURE_STEPS
    map_radius: float = 80.0
    map_selection: str = "agents"
    map_ahead_s: float = 8.0
    map_ahead_min: float = 20.0
    dynamics: str = "unicycle"
    """The dynamics model (`model.dynamics.DYNAMICS`) whose inverse fits a stored sample's target actions
    (`langtraj.training.store`); it must be the model's (`model.dynamics`)."""
    text: bool = True
    text_dropout: float = 0.5
    history_dropout: float = 0.5
    heuristic_label_fraction: float = 0.3
    interaction_fraction: float = 0.5
    decision_first: bool = False
    """Single-agent sentences go first to the agents that make a decision after the current step (`decision`
    events of synthesized scenes: what history cannot show); the share fills up with the others."""

    def __post_init__(self) -> None:
        for name in ("max_agents", "max_polylines", "history_steps"):
            if getattr(self, name) < 1:
                raise InputError(f"must be >= 1, got {getattr(self, name)}", where=f"data.{name}")
        if self.points_per_polyline < 2:
            raise InputError(f"must be >= 2, got {self.points_per_polyline}", where="data.points_per_polyline")
        if self.future_steps < 0:
            raise InputError(f"must be >= 0, got {self.future_steps}", where="data.future_steps")
        for name in ("map_radius", "map_ahead_s", "map_ahead_min"):
            if not getattr(self, name) > 0:
                raise InputError(f"must be > 0, got {getattr(self, name)}", where=f"data.{name}")
        if self.map_selection not in MAP_SELECTIONS:
            raise InputError(
                f"must be one of {', '.join(MAP_SELECTIONS)}, got {self.map_selection!r}", where="data.map_selection"
            )
        for name in ("text_dropout", "history_dropout", "heuristic_label_fraction", "interaction_fraction"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise InputError(f"must be in [0, 1], got {getattr(self, name)}", where=f"data.{name}")

    def for_agents(self, num_agents: int) -> SampleConfig:
        """The sizes for driving `num_agents` agents with a model trained on these samples: that many agent
        slots, the map budget scaled by the trained pieces per agent (never below it), no dropout. The
        network takes any number of agents and pieces; the map must still cover every one of them."""
        scale = max(num_agents / self.max_agents, 1.0)
        return replace(
            self.for_inference(self.text),
            max_agents=max(num_agents, 1),
            max_polylines=math.ceil(self.max_polylines * scale - 1e-9),
        )

    def for_inference(self, text: bool) -> SampleConfig:
        """These samples as a trained model is fed them: no text or history dropout, text on or off."""
        return replace(self, text=text, text_dropout=0.0, history_dropout=0.0)

    def local_attention(self) -> LocalAttention:
        """The neighbourhood a model trained on these samples saw: its agent slots and map pieces."""
        return LocalAttention(agents=self.max_agents, map_pieces=self.max_polylines)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any] | None, where: str = "data") -> SampleConfig:
        try:
            return cls(**dataclass_kwargs(cls, data, where))
        except TypeError as exc:
            raise InputError(str(exc), where=where) from None


@dataclass(frozen=True)
class LocalAttention:
    """Local attention for scenes larger than a model's training scenes: each agent attends to its `agents`
    nearest agents (itself included) and its `map_pieces` nearest map pieces only, so it sees a
    neighbourhood of the size it was trained on, and the pose terms grow with the agents instead of their
    square (docs/model.md, 'Local attention'). A scene within both budgets is attended densely."""

    agents: int
    map_pieces: int

    def __post_init__(self) -> None:
        for name in ("agents", "map_pieces"):
            if getattr(self, name) < 1:
                raise InputError(f"must be >= 1, got {getattr(self, name)}", where=f"local attention {name}")
