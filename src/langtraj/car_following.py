"""The Intelligent Driver Model's interaction term (Treiber, Hennecke and Helbing 2000), the one car-following law of
the project: the IDM planner keeps its distance with it (`planners.idm`), and a scripted adversary keeps off the
traffic ahead of it (`interdrive.behaviours.scripts`). Pure numpy."""

from __future__ import annotations

import math

import numpy as np

MIN_GAP_M = 0.1
"""The least gap (m) the interaction term divides by: an overlap brakes as hard as a gap of 10 cm."""


def idm_interaction(
    speed: float,
    gaps: np.ndarray,
    lead_speeds: np.ndarray,
    *,
    max_accel: float,
    comfortable_decel: float,
    time_headway: float,
    min_gap: float,
) -> np.ndarray:
    """The IDM's interaction term -a (s* / s)^2 per leader (m/s^2), s* = s0 + max(0, v T + v dv / (2 sqrt(a b))):
    `gaps` bumper to bumper (m) and the leaders' `lead_speeds` along the follower's way (m/s) for a follower at
    `speed`."""
    approach = speed - np.asarray(lead_speeds, np.float64)
    wanted = min_gap + np.maximum(
        0.0, speed * time_headway + speed * approach / (2.0 * math.sqrt(max_accel * comfortable_decel))
    )
    return -max_accel * (wanted / np.maximum(np.asarray(gaps, np.float64), MIN_GAP_M)) ** 2
