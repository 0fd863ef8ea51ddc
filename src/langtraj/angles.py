"""Angle conventions shared by every module: headings and heading differences wrapped to (-pi, pi].

`wrap_angle` is the one angle wrap, for floats, numpy arrays and torch tensors alike. Only
`metrics.kinematics` keeps its own wrap, to [-pi, pi) in the input's float32, because it follows the
official WOSAC code to 1e-7.
"""

from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING, Any, overload

import numpy as np

if TYPE_CHECKING:
    from torch import Tensor


@overload
def wrap_angle(angle: Tensor) -> Tensor: ...
@overload
def wrap_angle(angle: np.ndarray | float | Any) -> np.ndarray: ...


def wrap_angle(angle: Any) -> Any:
    """Angles wrapped to (-pi, pi]: a torch tensor stays one (its dtype, device and graph); anything else becomes
    float64 numpy. Torch is not imported here: a tensor exists only if it was."""
    torch = sys.modules.get("torch")
    if torch is not None and isinstance(angle, torch.Tensor):
        return math.pi - (math.pi - angle) % (2 * math.pi)
    return np.pi - np.mod(np.pi - np.asarray(angle, np.float64), 2 * np.pi)
