"""The LangTraj model: query-centric scene encoder, language encoder with LoRA, transformer denoiser,
and diffusion over unicycle actions (docs/design.md, 'The model'; docs/model.md)."""

from langtraj.model.batch import SceneBatch
from langtraj.model.config import ModelConfig
from langtraj.model.langtraj import LangTraj

__all__ = ["LangTraj", "ModelConfig", "SceneBatch"]
