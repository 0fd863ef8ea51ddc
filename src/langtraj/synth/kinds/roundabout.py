"""Roundabout kind: a one- or two-lane circular junction with 3-5 arms. See docs/data.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from langtraj.synth.kinds.xmlfiles import (
    KMH,
    Arm,
    Connection,
    Edge,
    Node,
    PlainNetwork,
    arm_elements,
    build,
    chance,
    integer,
    net_point,
    polar,
    read_net,
    uniform,
)
from langtraj.synth.network import BuiltNetwork, InterestCentre, NetworkKind, register_kind

ARC_STEP_DEG = 10.0
"""Angular spacing of the shape points of the ring edges."""


def _arm_angles(rng: np.random.Generator, arms: int) -> list[float]:
    """Arm directions spread around the circle, each jittered by up to a 0.15 of the spacing."""
    rotation = float(rng.uniform(0.0, 360.0))
    spacing = 360.0 / arms
    return [round((rotation + i * spacing + float(rng.uniform(-0.15, 0.15)) * spacing) % 360.0, 1) for i in range(arms)]


def _arc(radius: float, start: float, end: float) -> tuple[tuple[float, float], ...]:
    """Points of the counter-clockwise arc from angle `start` to `end` (degrees) at `radius`."""
    sweep = (end - start) % 360.0
    steps = max(2, int(np.ceil(sweep / ARC_STEP_DEG)))
    return tuple(polar(radius, start + sweep * k / steps) for k in range(steps + 1))


def _ring(
    radius: float, angles: list[float], lanes: int, speed: float, sidewalk: float
) -> tuple[list[Node], list[Edge]]:
    """Ring nodes `r<i>` at the arm angles and counter-clockwise ring edges `ring<i>` between them."""
    order = sorted(range(len(angles)), key=lambda i: angles[i])
    nodes = [Node(f"r{i}", *polar(radius, angles[i])) for i in range(len(angles))]
    edges = []
    for k, i in enumerate(order):
        j = order[(k + 1) % len(order)]
        shape = _arc(radius, angles[i], angles[j])
        edges.append(Edge(f"ring{i}", f"r{i}", f"r{j}", lanes, speed, priority=5, sidewalk=sidewalk, shape=shape))
    return nodes, edges


def _two_lane_exits(ring_edges: list[Edge], sidewalk: bool) -> tuple[Connection, ...]:
    """Connections of a two-lane ring: both ring lanes continue and both may exit into a two-lane arm
    (netconvert only exits from the outer lane, which gridlocks the inner lane under load)."""
    offset = 1 if sidewalk else 0
    by_node = {e.from_node: e.id for e in ring_edges}
    connections = []
    for edge in ring_edges:
        exit_arm = f"arm{edge.to_node[1:]}_out"
        for lane in (offset, offset + 1):
            connections.append(Connection(edge.id, by_node[edge.to_node], lane, lane))
            connections.append(Connection(edge.id, exit_arm, lane, lane))
    return tuple(connections)


@register_kind
class Roundabout(NetworkKind):
    """Roundabout with 3-5 arms, single- or two-lane ring, optional sidewalks with crossings."""

    name = "roundabout"
    description = "single- or two-lane roundabout with 3-5 arms, optional sidewalks and crosswalks"

    def build(self, rng: np.random.Generator, workdir: Path) -> BuiltNetwork:
        """Draw arms, ring size and lanes, speeds and sidewalks; build with an explicit roundabout."""
        n_arms = integer(rng, 3, 5)
        two_lane = chance(rng, 0.4)
        radius = uniform(rng, 20.0, 28.0) if two_lane else uniform(rng, 14.0, 20.0)
        radius = round(radius + 3.0 * (n_arms - 3), 1)  # room for the arm junctions on the ring
        ring_speed, arm_speed = uniform(rng, 25.0, 35.0), uniform(rng, 40.0, 60.0)
        sidewalk = uniform(rng, 2.0, 3.0, 2) if chance(rng, 0.7) else 0.0
        angles = _arm_angles(rng, n_arms)
        nodes, edges = _ring(radius, angles, 2 if two_lane else 1, ring_speed * KMH, sidewalk)
        arms = []
        for i, angle in enumerate(angles):
            lanes = integer(rng, 1, 2) if two_lane else 1
            length = uniform(rng, 130.0, 200.0)
            arm = Arm(f"arm{i}", angle, length, lanes, 2 if two_lane else 1, arm_speed * KMH, sidewalk=sidewalk)
            arm_nodes, arm_edges = arm_elements(f"r{i}", (nodes[i].x, nodes[i].y), arm)
            arms.append(arm)
            nodes += arm_nodes
            edges += arm_edges
        ring = (tuple(n.id for n in nodes[:n_arms]), tuple(e.id for e in edges[:n_arms]))
        connections = _two_lane_exits(edges[:n_arms], sidewalk > 0) if two_lane else ()
        options = ("--crossings.guess", "true") if sidewalk else ()
        plain = PlainNetwork(tuple(nodes), tuple(edges), connections, roundabouts=(ring,), options=options)
        net_file = build(plain, workdir, self.name)
        x, y = net_point(read_net(net_file), 0.0, 0.0)
        centre = InterestCentre(x, y, round(radius + 35.0, 1), "junction")
        params: dict[str, object] = {
            "arms": n_arms,
            "two_lane": two_lane,
            "radius_m": radius,
            "ring_speed_kmh": ring_speed,
            "arm_speed_kmh": arm_speed,
            "sidewalk_m": sidewalk,
            "arm_angles_deg": angles,
            "arm_lanes_in": [a.lanes_in for a in arms],
            "arm_lengths_m": [a.length for a in arms],
        }
        return BuiltNetwork(self.name, net_file, (centre,), params, pedestrians=sidewalk > 0, bicycles=False)
