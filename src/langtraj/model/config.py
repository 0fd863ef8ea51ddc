"""Model configuration: sizes, diffusion, dynamics and text encoder, as one documented dataclass."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from langtraj.model.text_encoder import TextEncoderConfig


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
    history_steps: int = 11  # history length the encoder reads (10 Hz, ending at the current step)
    num_actions: int = 16  # 0.5 s actions: 16 cover 8 s
    dynamics: str = "unicycle"
    vehicle_max_curvature: float = 0.25  # 1/m (a 4 m turn radius): vehicles cannot turn on the spot
    action_scale: tuple[float, float] = (4.0, 0.5)  # m/s^2 and rad/s that map to 1 in the network's units
    diffusion_steps: int = 100  # K (paper: 100 for pretraining)
    map_attention_radius: float = 50.0  # map polylines attend to polylines within this distance (m)
    text: TextEncoderConfig = field(default_factory=TextEncoderConfig)
    use_text: bool = True  # build the language branch (stage 2); stage 1 can skip it

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ModelConfig:
        data = dict(data)
        text = TextEncoderConfig(**data.pop("text", {}))
        if "action_scale" in data:
            data["action_scale"] = tuple(data["action_scale"])
        return cls(text=text, **data)
