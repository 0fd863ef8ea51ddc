"""Target actions: the clean actions a window's logged future asks of the model, fitted once per window.

The denoising loss needs, for every agent, the actions whose integration reproduces its logged future
(`Dynamics.inverse`, a block-by-block Gauss-Newton fit). They depend on the window alone, so a feature store
computes them when it is built (`langtraj.training.store`) and training reads them from the batch
(`SceneBatch.target_actions`) instead of refitting the same data at every step (docs/model.md, 'Target
actions'). Without stored targets (windows decoded on the fly, futures that closed-loop training moved on) the
model fits them itself, with the same function.

See docs/model.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import Tensor

from langtraj.model.dynamics import DYNAMICS, Dynamics

TARGET_ARRAYS: dict[str, type[np.generic]] = {"target_actions": np.float32, "target_valid": np.bool_}
"""The arrays a stored sample adds to `features.SAMPLE_ARRAYS`: actions [A, N, 2] in physical units (within the
dynamics' bounds) and where they are defined [A, N], for N = future_steps // steps_per_action."""


def fit_actions(
    dynamics: Dynamics, current: Tensor, future: Tensor, future_valid: Tensor, agent_valid: Tensor, num_actions: int
) -> tuple[Tensor, Tensor]:
    """Physical actions [..., N, 2] that take `current` [..., A, 4] along the first `num_actions` actions' steps
    of `future` [..., A, >= T, 3], and where they are defined (bool [..., A, N]): the one definition of a
    target, for the store and the model alike."""
    steps = num_actions * dynamics.steps_per_action
    with torch.no_grad():
        actions, valid = dynamics.inverse(current, future[..., :steps, :], future_valid[..., :steps])
    return actions, valid & agent_valid[..., None]


def stored_targets(samples: list[dict[str, Any]], dynamics: str) -> dict[str, np.ndarray]:
    """`TARGET_ARRAYS` [n, ...] for `scene_sample` dicts of equal sizes, fitted over each sample's whole future
    by `dynamics` (a `DYNAMICS` name) in one batched call: what a feature store keeps beside the samples."""
    model = DYNAMICS.create(dynamics, where="data.dynamics")

    def stack(name: str) -> Tensor:
        return torch.from_numpy(np.stack([s[name] for s in samples]))

    future = stack("future")
    actions, valid = fit_actions(
        model,
        stack("current_state"),
        future,
        stack("future_valid"),
        stack("agent_valid"),
        future.shape[-2] // model.steps_per_action,
    )
    return {"target_actions": actions.numpy().astype(np.float32), "target_valid": valid.numpy()}
