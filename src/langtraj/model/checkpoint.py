"""LangTraj checkpoints without the training framework: the file layout, its checks, and `load_model`,
which rebuilds a trained model and the sample configuration it was trained with (docs/model.md,
'Checkpoints').

A checkpoint is a `torch.save`d dict: `langtraj_format`, `hyper_parameters["config"]` (the training
configuration, whose `model` and `data` sections are `ModelConfig` and `SampleConfig`) and `state_dict`
(the model's weights under the `model.` prefix, without the frozen pretrained text-encoder weights,
which load from the encoder's package). Training writes it (`langtraj.training.module`); simulation,
sampling and the experiments read it here.
"""

from __future__ import annotations

from collections.abc import Mapping, MutableMapping
from pathlib import Path
from typing import Any

import torch

from langtraj.errors import InputError
from langtraj.model.config import ModelConfig, SampleConfig
from langtraj.model.langtraj import LangTraj

CHECKPOINT_FORMAT = 1
"""Bumped when a checkpoint's layout changes; loading another format is refused."""

WEIGHTS_PREFIX = "model."
"""The model's weights in a checkpoint's `state_dict` carry this prefix (the training module's attribute)."""

OBSOLETE_KEYS = frozenset({"model.text_encoder.null_embedding"})
"""Weights earlier versions saved that nothing reads any more (the text encoder's null embedding, which
the model's own null condition always replaced): dropped when a checkpoint loads."""

FROZEN_PREFIX = "model.text_encoder.encoder."
"""Pretrained text-encoder weights: not stored in checkpoints (they load from the encoder's package)."""


def read_checkpoint(path: str | Path) -> dict[str, Any]:
    """A LangTraj checkpoint, checked for its format; errors name the file."""
    path = Path(path)
    try:
        checkpoint = torch.load(path, map_location="cpu", weights_only=True)  # never runs code from the file
    except FileNotFoundError:
        raise InputError("no such checkpoint", path=path) from None
    except IsADirectoryError:
        raise InputError("is a folder, not a checkpoint file", path=path) from None
    except Exception as exc:  # torch raises many kinds for a truncated or foreign file
        raise InputError(f"not a readable checkpoint ({type(exc).__name__}: {exc})", path=path) from None
    if not isinstance(checkpoint, dict) or checkpoint.get("langtraj_format") != CHECKPOINT_FORMAT:
        found = checkpoint.get("langtraj_format") if isinstance(checkpoint, dict) else None
        raise InputError(f"not a LangTraj checkpoint of format {CHECKPOINT_FORMAT} (found {found!r})", path=path)
    return checkpoint


def strip_frozen(state: MutableMapping[str, Any]) -> None:
    """Drop the frozen pretrained text-encoder weights (LoRA weights stay) from a state dict being saved."""
    for key in [k for k in state if k.startswith(FROZEN_PREFIX) and "lora_" not in k]:
        del state[key]


def restore_frozen(state: MutableMapping[str, Any], own: Mapping[str, Any]) -> None:
    """Complete a loaded state dict: drop `OBSOLETE_KEYS`, and take the frozen encoder weights it lacks
    from `own` (a freshly built model's state dict, whose encoder loaded them from its package)."""
    for key in OBSOLETE_KEYS & set(state):
        del state[key]
    for key, value in own.items():
        if key.startswith(FROZEN_PREFIX) and key not in state:
            state[key] = value


def check_keys(own: Mapping[str, Any], saved: Mapping[str, Any], path: str | Path) -> None:
    """InputError naming the first missing and unexpected weights when the two key sets differ."""
    mine, theirs = set(own), set(saved)
    if mine == theirs:
        return
    missing, unexpected = sorted(mine - theirs), sorted(theirs - mine)
    raise InputError(
        "weights do not match this version of the model"
        + (f"; missing {', '.join(missing[:4])}{' ...' if len(missing) > 4 else ''}" if missing else "")
        + (f"; unexpected {', '.join(unexpected[:4])}{' ...' if len(unexpected) > 4 else ''}" if unexpected else ""),
        path=path,
    )


def checkpoint_configs(checkpoint: Mapping[str, Any], path: str | Path) -> tuple[ModelConfig, SampleConfig]:
    """The model and sample configurations a checkpoint was trained with. Checkpoints from before map
    coverage record no `map_selection`: they saw the pieces nearest the origin, and keep doing so."""
    try:
        config = checkpoint["hyper_parameters"]["config"]
        data = {"map_selection": "origin", **(config.get("data") or {})}
        return ModelConfig.from_dict(config.get("model")), SampleConfig.from_dict(data)
    except (KeyError, TypeError, AttributeError):
        raise InputError("has no training configuration (hyper_parameters.config)", path=path) from None
    except InputError as exc:
        raise exc.located(path=path) from None


def load_model(path: str | Path) -> tuple[LangTraj, SampleConfig]:
    """The trained model of a checkpoint, in eval mode on the CPU, and the `SampleConfig` it was trained
    with (what its inputs must look like)."""
    checkpoint = read_checkpoint(path)
    model_config, sample_config = checkpoint_configs(checkpoint, path)
    model = LangTraj(model_config)
    own = {WEIGHTS_PREFIX + k: v for k, v in model.state_dict().items()}
    state = dict(checkpoint["state_dict"])
    restore_frozen(state, own)
    check_keys(own, state, path)
    model.load_state_dict({k[len(WEIGHTS_PREFIX) :]: v for k, v in state.items()})
    return model.eval(), sample_config
