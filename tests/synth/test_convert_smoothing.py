"""SUMO -> Scenario coordinate conversions and the 10 Hz repairs of SUMO's tracks."""

from __future__ import annotations

import numpy as np
import pytest

from langtraj.angles import wrap_angle
from langtraj.synth.convert import centre_from_front, heading_from_sumo_angle, sumo_angle_from_heading
from langtraj.synth.smoothing import (
    MAX_CURVATURE,
    YAW_ALLOWANCE,
    heading_from_motion,
    limit_yaw_rate,
    moving_average,
    remove_jumps,
    smooth_pedestrian,
)


@pytest.mark.parametrize(
    ("angle", "heading"),
    [(0.0, np.pi / 2), (90.0, 0.0), (180.0, -np.pi / 2), (270.0, np.pi), (45.0, np.pi / 4), (359.0, np.radians(91))],
)
def test_sumo_angle_is_clockwise_from_north(angle, heading):
    assert heading_from_sumo_angle(angle) == pytest.approx(heading)
    assert sumo_angle_from_heading(heading) == pytest.approx(angle % 360)


def test_headings_wrap_to_half_open_interval():
    wrapped = wrap_angle(np.array([np.pi, -np.pi, 3 * np.pi, -3 * np.pi + 1e-9, 0.5]))
    assert np.all(wrapped > -np.pi) and np.all(wrapped <= np.pi)
    assert wrapped[:3] == pytest.approx([np.pi] * 3)


def test_centre_is_half_a_length_behind_the_front_bumper():
    front = np.array([[10.0, 5.0], [0.0, 0.0]])
    heading = heading_from_sumo_angle(np.array([90.0, 0.0]))  # driving east, driving north
    centre = centre_from_front(front, heading, np.array([4.0, 12.0]))
    assert centre == pytest.approx(np.array([[8.0, 5.0], [0.0, -6.0]]))


def test_stopped_vehicle_does_not_turn_sideways():
    """Mid lane change at standstill SUMO swings the angle towards the lateral motion; ours stays."""
    heading = np.concatenate([np.zeros(20), np.full(20, np.pi / 2)])  # 90 degree swing at once
    speed = np.concatenate([np.full(10, 5.0), np.zeros(30)])
    out = limit_yaw_rate(heading, speed)
    assert np.abs(out[20:]).max() <= 20 * YAW_ALLOWANCE + 1e-9
    assert np.abs(np.diff(out)).max() <= 5.0 * MAX_CURVATURE * 0.1 + YAW_ALLOWANCE + 1e-9


def test_turning_vehicle_keeps_its_heading():
    t = np.arange(50)
    heading = wrap_angle(0.05 * t)  # 0.5 rad/s at 10 m/s: curvature 0.05, well within the limit
    assert limit_yaw_rate(heading, np.full(50, 10.0)) == pytest.approx(heading)


def test_pedestrian_jump_is_removed_without_moving_the_end():
    xy = np.stack([np.arange(60) * 0.13, np.zeros(60)], axis=1)
    xy[30:, 1] += 2.0  # a 2 m sideways jump at a walking area
    fixed = remove_jumps(xy)
    assert np.linalg.norm(np.diff(fixed, axis=0), axis=1).max() < 0.45
    assert fixed[-1] == pytest.approx(xy[-1])
    assert fixed[:30] == pytest.approx(xy[:30])


def test_moving_average_keeps_ends_and_straight_lines():
    line = np.stack([np.arange(20.0), 2 * np.arange(20.0)], axis=1)
    assert moving_average(line) == pytest.approx(line)


def test_pedestrian_heading_follows_motion_and_is_held_when_standing():
    walk = np.stack([np.zeros(20), np.arange(20) * 0.12], axis=1)  # north at 1.2 m/s
    xy = np.concatenate([walk, np.repeat(walk[-1:], 20, axis=0)])
    heading = heading_from_motion(xy, np.zeros(40))
    assert heading[:18] == pytest.approx(np.pi / 2)
    assert heading[25:] == pytest.approx(np.pi / 2)  # held while standing, not the SUMO angle
    smoothed, h = smooth_pedestrian(xy, np.zeros(40))
    assert smoothed.shape == xy.shape and h.shape == (40,)
