"""Angle conventions shared by every module: headings and heading differences wrapped to (-pi, pi].

`wrap_angle` is the one angle wrap, for floats, numpy arrays and torch tensors alike. Two places keep
[-pi, pi) instead, through `wrap_angle(..., interval="[-pi, pi)")` (the training losses' heading error,
whose rounding changes with the formula) or their own copy (`metrics.kinematics`, which follows the
official WOSAC code in the input's float32).
"""

from __future__ import annotations

import math
import sys
from typing import Any, Literal

import numpy as np

Interval = Literal["(-pi, pi]", "[-pi, pi)"]


def _is_tensor(angle: Any) -> bool:
    """Whether `angle` is a torch tensor (torch is not imported here: a tensor exists only if it was)."""
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(angle, torch.Tensor)


def wrap_angle(angle: Any, interval: Interval = "(-pi, pi]") -> Any:
    """Angles wrapped to (-pi, pi] (or [-pi, pi)): a torch tensor stays one (its dtype, device and graph);
    anything else becomes float64 numpy."""
    if _is_tensor(angle):
        if interval == "(-pi, pi]":
            return math.pi - (math.pi - angle) % (2 * math.pi)
        if interval == "[-pi, pi)":
            return (angle + math.pi) % (2 * math.pi) - math.pi
    else:
        if interval == "(-pi, pi]":
            return np.pi - np.mod(np.pi - np.asarray(angle, np.float64), 2 * np.pi)
        if interval == "[-pi, pi)":
            return np.mod(np.asarray(angle, np.float64) + np.pi, 2 * np.pi) - np.pi
    raise ValueError(f"interval must be '(-pi, pi]' or '[-pi, pi)', got {interval!r}")
