"""Arterial kind: a multi-lane urban main road through 2-4 signalized intersections with side streets.

See docs/data.md.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from langtraj.synth.kinds.xmlfiles import (
    KMH,
    SIGNAL_OPTIONS,
    Arm,
    Edge,
    Node,
    PlainNetwork,
    arm_elements,
    built_junctions,
    chance,
    integer,
    rotate,
    two_way,
    uniform,
)
from langtraj.synth.network import BuiltNetwork, NetworkKind, register_kind


def _main_nodes(rng: np.random.Generator, junctions: int) -> list[Node]:
    """W, I1..In, E along the x axis: signalized intersections 130-200 m apart, a little off a line."""
    gaps = [uniform(rng, 120.0, 170.0)] + [uniform(rng, 130.0, 200.0) for _ in range(junctions - 1)]
    gaps.append(uniform(rng, 120.0, 170.0))
    xs = np.cumsum(gaps).round(1).tolist()
    nodes = [Node("W", 0.0, 0.0)]
    nodes += [Node(f"I{i + 1}", xs[i], uniform(rng, -6.0, 6.0), "traffic_light") for i in range(junctions)]
    nodes.append(Node("E", xs[-1], 0.0))
    return nodes


@register_kind
class Arterial(NetworkKind):
    """Multi-lane arterial with 2-4 signalized intersections: lane changes, overtaking, queues."""

    name = "arterial"
    description = "2-3 lanes per direction arterial (50-70 km/h) through 2-4 signalized intersections"

    def build(self, rng: np.random.Generator, workdir: Path) -> BuiltNetwork:
        """Draw junction count and spacing, lanes, speeds, side streets, sidewalks, bike lanes, timing."""
        rotation = uniform(rng, 0.0, 360.0)
        junctions = integer(rng, 2, 4)
        lanes, speed, side_speed = integer(rng, 2, 3), uniform(rng, 50.0, 70.0), uniform(rng, 30.0, 50.0)
        sidewalk = uniform(rng, 2.0, 3.0, 2) if chance(rng, 0.6) else 0.0
        bike_lane = uniform(rng, 1.5, 2.0, 2) if chance(rng, 0.4) else 0.0
        green, yellow = integer(rng, 8, 14), integer(rng, 3, 4)
        side = {"sidewalk": sidewalk, "bike_lane": bike_lane}
        nodes = _main_nodes(rng, junctions)
        edges: list[Edge] = []
        for a, b in itertools.pairwise(nodes):
            edges += two_way(a.id, b.id, lanes, speed * KMH, priority=3, **side)
        streets = []
        for node in nodes[1:-1]:
            for direction, base in (("n", 90.0), ("s", 270.0)):
                if direction == "s" and not chance(rng, 0.7):
                    continue
                length = uniform(rng, 80.0, 130.0)
                angle = round(base + float(rng.uniform(-10.0, 10.0)), 1)
                arm = Arm(f"{direction}{node.id[1:]}", angle, length, 1, 1, side_speed * KMH, **side)
                arm_nodes, arm_edges = arm_elements(node.id, (node.x, node.y), arm)
                nodes += arm_nodes
                edges += arm_edges
                streets.append({"name": arm.name, "angle_deg": angle, "length_m": length})
        options = [*SIGNAL_OPTIONS, "--tls.green.time", str(green), "--tls.yellow.time", str(yellow)]
        if sidewalk:
            options += ["--crossings.guess", "true"]
        plain = rotate(PlainNetwork(tuple(nodes), tuple(edges), options=tuple(options)), rotation)
        params: dict[str, object] = {
            "rotation_deg": rotation,
            "junctions": junctions,
            "lanes": lanes,
            "speed_kmh": speed,
            "side_speed_kmh": side_speed,
            "sidewalk_m": sidewalk,
            "bike_lane_m": bike_lane,
            "green_s": green,
            "yellow_s": yellow,
            "junction_x_m": [n.x for n in nodes[1 : junctions + 1]],
            "side_streets": streets,
        }
        ids = [f"I{i}" for i in range(1, junctions + 1)]
        return built_junctions(
            self.name, plain, workdir, ids, 50.0, params, pedestrians=sidewalk > 0, bicycles=bike_lane > 0
        )
