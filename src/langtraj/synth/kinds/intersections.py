"""Single intersections: signalized 4-way, priority junction with stop signs, all-way stop. See docs/data.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from langtraj.synth.kinds.xmlfiles import (
    KMH,
    SIGNAL_OPTIONS,
    Arm,
    Node,
    built_junctions,
    chance,
    integer,
    star,
    uniform,
)
from langtraj.synth.network import BuiltNetwork, NetworkKind, register_kind

_ARM_NAMES = ("east", "north", "west", "south")
"""Arm names by base direction (counter-clockwise from east)."""

PEDESTRIAN_OPTIONS: tuple[str, ...] = ("--crossings.guess", "true")
"""netconvert options of kinds with sidewalks: crossings wherever sidewalks meet a junction."""


def _angle(rng: np.random.Generator, rotation: float, index: int, jitter: float) -> float:
    """Direction of the arm `index` (0 east, 1 north, ...) of a junction rotated by `rotation` degrees."""
    return round((rotation + 90.0 * index + float(rng.uniform(-jitter, jitter))) % 360.0, 1)


def _arm_params(arms: list[Arm]) -> list[dict[str, object]]:
    """The drawn geometry of each arm, for BuiltNetwork.params."""
    return [
        {"name": a.name, "angle_deg": a.angle, "length_m": a.length, "lanes_in": a.lanes_in, "bay_m": a.bay_length}
        for a in arms
    ]


@register_kind
class Signalized(NetworkKind):
    """Signalized 4-way intersection with sidewalks, crosswalks and bike lanes."""

    name = "signalized"
    description = (
        "signalized 4-way intersection, 1-3 lanes per approach, optional left-turn bays, crosswalks, bike lanes"
    )

    def build(self, rng: np.random.Generator, workdir: Path) -> BuiltNetwork:
        """Draw lanes, speeds, angles, bays and signal timings; build the junction with netconvert."""
        rotation = uniform(rng, 0.0, 360.0)
        major_lanes = integer(rng, 1, 3)
        minor_lanes = integer(rng, 1, min(2, major_lanes))
        speeds = (uniform(rng, 40.0, 60.0), uniform(rng, 30.0, 50.0))
        bay = uniform(rng, 25.0, 45.0) if chance(rng, 0.6) else 0.0
        sidewalk, bike_lane = uniform(rng, 2.0, 3.0, 2), uniform(rng, 1.5, 2.0, 2)
        # The incoming layout gives each approach its own phase: the red time is three other phases,
        # which must stay well under the 90 s teleport time.
        green, yellow = integer(rng, 8, 15), integer(rng, 3, 4)
        arms = []
        for i, arm_name in enumerate(_ARM_NAMES):
            major = i % 2 == 0
            lanes = major_lanes if major else minor_lanes
            arms.append(
                Arm(
                    arm_name,
                    _angle(rng, rotation, i, 8.0),
                    uniform(rng, 100.0, 170.0),
                    lanes,
                    lanes,
                    (speeds[0] if major else speeds[1]) * KMH,
                    priority=2 if major else 1,
                    sidewalk=sidewalk,
                    bike_lane=bike_lane,
                    bay_length=bay if major else 0.0,
                )
            )
        timing = ["--tls.green.time", str(green), "--tls.yellow.time", str(yellow)]
        plain = star(Node("C", 0.0, 0.0, "traffic_light"), arms, [*SIGNAL_OPTIONS, *PEDESTRIAN_OPTIONS, *timing])
        params: dict[str, object] = {
            "major_lanes": major_lanes,
            "minor_lanes": minor_lanes,
            "major_speed_kmh": speeds[0],
            "minor_speed_kmh": speeds[1],
            "left_turn_bay_m": bay,
            "sidewalk_m": sidewalk,
            "bike_lane_m": bike_lane,
            "green_s": green,
            "yellow_s": yellow,
            "arms": _arm_params(arms),
        }
        radius = 45.0 + 5.0 * major_lanes
        return built_junctions(self.name, plain, workdir, ["C"], radius, params, pedestrians=True, bicycles=True)


@register_kind
class Priority(NetworkKind):
    """Priority junction: a major road through, minor approaches with stop signs."""

    name = "priority"
    description = "priority 3- or 4-way junction, major road through, stop signs on the minor road, zebras"

    def build(self, rng: np.random.Generator, workdir: Path) -> BuiltNetwork:
        """Draw arms, lanes, speeds and whether there are sidewalks; build a `priority_stop` junction."""
        rotation = uniform(rng, 0.0, 360.0)
        four_way = chance(rng, 0.5)
        major_lanes = integer(rng, 1, 2)
        speeds = (uniform(rng, 40.0, 60.0), uniform(rng, 30.0, 50.0))
        sidewalk = uniform(rng, 2.0, 3.0, 2) if chance(rng, 0.8) else 0.0
        arms = []
        for i, arm_name in enumerate(_ARM_NAMES[: 4 if four_way else 3]):
            major = i % 2 == 0
            lanes = major_lanes if major else 1
            speed = (speeds[0] if major else speeds[1]) * KMH
            angle = _angle(rng, rotation, i, 5.0 if major else 20.0)
            length = uniform(rng, 150.0, 230.0)
            arms.append(
                Arm(arm_name, angle, length, lanes, lanes, speed, priority=3 if major else 1, sidewalk=sidewalk)
            )
        # Zebra crossings: with guessed crossings pedestrians must find gaps and turning cars hit them.
        plain = star(Node("C", 0.0, 0.0, "priority_stop"), arms, (), zebras=sidewalk > 0)
        params: dict[str, object] = {
            "four_way": four_way,
            "major_lanes": major_lanes,
            "major_speed_kmh": speeds[0],
            "minor_speed_kmh": speeds[1],
            "sidewalk_m": sidewalk,
            "arms": _arm_params(arms),
        }
        pedestrians = sidewalk > 0
        return built_junctions(self.name, plain, workdir, ["C"], 50.0, params, pedestrians=pedestrians, bicycles=False)


@register_kind
class AllWay(NetworkKind):
    """All-way stop junction with single-lane approaches, sidewalks and crossings."""

    name = "allway"
    description = "all-way stop, 3- or 4-way, single-lane approaches, sidewalks and crosswalks"

    def build(self, rng: np.random.Generator, workdir: Path) -> BuiltNetwork:
        """Draw arms, speed and sidewalk width; build an `allway_stop` junction."""
        rotation = uniform(rng, 0.0, 360.0)
        four_way = chance(rng, 0.6)
        speed = uniform(rng, 30.0, 50.0)
        sidewalk = uniform(rng, 2.0, 3.0, 2)
        arms = []
        for i, arm_name in enumerate(_ARM_NAMES[: 4 if four_way else 3]):
            angle, length = _angle(rng, rotation, i, 12.0), uniform(rng, 150.0, 230.0)
            arms.append(Arm(arm_name, angle, length, 1, 1, speed * KMH, sidewalk=sidewalk))
        plain = star(Node("C", 0.0, 0.0, "allway_stop"), arms, (), zebras=True)
        params: dict[str, object] = {
            "four_way": four_way,
            "speed_kmh": speed,
            "sidewalk_m": sidewalk,
            "arms": _arm_params(arms),
        }
        return built_junctions(self.name, plain, workdir, ["C"], 45.0, params, pedestrians=True, bicycles=False)
