"""Coordinate conventions between SUMO and the Scenario model.

SUMO reports a vehicle's position at the middle of its front bumper and its angle in degrees clockwise
from north; the Scenario model wants box centres and headings in radians counter-clockwise from east,
wrapped to (-pi, pi].

See docs/data.md.
"""

from __future__ import annotations

import numpy as np

from langtraj.angles import wrap_angle


def heading_from_sumo_angle(angle_deg: np.ndarray | float) -> np.ndarray:
    """SUMO angle (degrees, clockwise from north) to heading (radians, counter-clockwise from east)."""
    return wrap_angle(np.pi / 2 - np.radians(angle_deg))


def sumo_angle_from_heading(heading: np.ndarray | float) -> np.ndarray:
    """Inverse of `heading_from_sumo_angle`, in [0, 360)."""
    return np.mod(90.0 - np.degrees(heading), 360.0)


def centre_from_front(front_xy: np.ndarray, heading: np.ndarray, length: float | np.ndarray) -> np.ndarray:
    """Box centre [..., 2] from the front-bumper middle, the heading and the box length."""
    front_xy = np.asarray(front_xy, np.float64)
    heading = np.asarray(heading, np.float64)
    half = 0.5 * np.asarray(length, np.float64)
    return front_xy - np.stack([np.cos(heading), np.sin(heading)], axis=-1) * half[..., None]
