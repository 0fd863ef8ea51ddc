"""Highway on-ramp kind: a multi-lane motorway that an on-ramp joins through an acceleration lane that
ends (the merge), optionally followed by an off-ramp with a deceleration lane. See docs/data.md."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from langtraj.synth.kinds.xmlfiles import (
    KMH,
    Connection,
    Edge,
    Node,
    PlainNetwork,
    build,
    chance,
    integer,
    read_net,
    rotate,
    uniform,
)
from langtraj.synth.network import BuiltNetwork, InterestCentre, NetworkKind, register_kind


def _ramp_start(end_x: float, length: float, angle_deg: float) -> tuple[float, float]:
    """Start of a straight on-ramp of `length` reaching the motorway (y = 0) at `end_x` from the right."""
    a = math.radians(angle_deg)
    return (round(end_x - length * math.cos(a), 2), round(-length * math.sin(a), 2))


def _ramp_end(start_x: float, length: float, angle_deg: float) -> tuple[float, float]:
    """End of a straight off-ramp of `length` leaving the motorway (y = 0) at `start_x` to the right."""
    a = math.radians(angle_deg)
    return (round(start_x + length * math.cos(a), 2), round(-length * math.sin(a), 2))


def _lane_shift(from_edge: str, to_edge: str, lanes: int, from_start: int, to_start: int) -> list[Connection]:
    """Lane from_start + i of `from_edge` to lane to_start + i of `to_edge` for i in 0..lanes-1."""
    return [Connection(from_edge, to_edge, from_start + i, to_start + i) for i in range(lanes)]


def _merge(lanes: int, v: float, vr: float, m1: float, m2: float, ramp: tuple[float, float]) -> PlainNetwork:
    """Motorway from H0 to M2 where the on-ramp joins an acceleration lane at M1 that ends at M2."""
    nodes = (Node("H0", 0.0, 0.0), Node("M1", m1, 0.0), Node("M2", m2, 0.0), Node("R", *_ramp_start(m1, *ramp)))
    edges = (
        Edge("main_in", "H0", "M1", lanes, v, priority=3),
        Edge("ramp_in", "R", "M1", 1, vr, priority=1),
        Edge("accel", "M1", "M2", lanes + 1, v, priority=3),
    )
    connections = [*_lane_shift("main_in", "accel", lanes, 0, 1), Connection("ramp_in", "accel", 0, 0)]
    connections += _lane_shift("accel", "main_mid", lanes, 1, 0)  # accel lane 0 ends: the merge
    return PlainNetwork(nodes, edges, tuple(connections))


def _diverge(lanes: int, v: float, vr: float, d1: float, d2: float) -> PlainNetwork:
    """Deceleration lane from D1 to D2 where the off-ramp leaves; the motorway goes on as `main_out`."""
    nodes = (Node("D1", d1, 0.0), Node("D2", d2, 0.0), Node("X", *_ramp_end(d2, 150.0, 10.0)))
    edges = (Edge("decel", "D1", "D2", lanes + 1, v, priority=3), Edge("ramp_out", "D2", "X", 1, vr, priority=1))
    connections = [*_lane_shift("main_mid", "decel", lanes, 0, 1), Connection("main_mid", "decel", 0, 0)]
    connections += [*_lane_shift("decel", "main_out", lanes, 1, 0), Connection("decel", "ramp_out", 0, 0)]
    return PlainNetwork(nodes, edges, tuple(connections))


@register_kind
class OnRamp(NetworkKind):
    """Multi-lane highway with an on-ramp merging through an acceleration lane (and maybe an off-ramp)."""

    name = "onramp"
    description = "2-4 lane highway (100-130 km/h) with an on-ramp merge via an ending acceleration lane"

    def build(self, rng: np.random.Generator, workdir: Path) -> BuiltNetwork:
        """Draw lanes, speeds, lengths and the off-ramp; build with explicit lane connections."""
        rotation = uniform(rng, 0.0, 360.0)
        lanes = integer(rng, 2, 4)
        speed, ramp_speed = uniform(rng, 100.0, 130.0), uniform(rng, 60.0, 80.0)
        upstream, accel = uniform(rng, 250.0, 350.0), uniform(rng, 150.0, 250.0)
        ramp_length, ramp_angle = uniform(rng, 150.0, 220.0), uniform(rng, 6.0, 12.0)
        off_ramp = chance(rng, 0.5)
        gap, decel = uniform(rng, 250.0, 400.0), uniform(rng, 100.0, 160.0)
        downstream = uniform(rng, 200.0, 300.0)
        v, vr = speed * KMH, ramp_speed * KMH
        m1, m2 = upstream, upstream + accel
        merge = _merge(lanes, v, vr, m1, m2, (ramp_length, ramp_angle))
        nodes, edges, connections = list(merge.nodes), list(merge.edges), list(merge.connections)
        last, end_x = "M2", m2 + gap
        if off_ramp:
            diverge = _diverge(lanes, v, vr, end_x, end_x + decel)
            nodes += diverge.nodes
            edges += [Edge("main_mid", "M2", "D1", lanes, v, priority=3), *diverge.edges]
            connections += diverge.connections
            last, end_x = "D2", end_x + decel
        nodes.append(Node("H9", round(end_x + downstream, 2), 0.0))
        edges.append(Edge("main_out" if off_ramp else "main_mid", last, "H9", lanes, v, priority=3))
        plain = rotate(PlainNetwork(tuple(nodes), tuple(edges), tuple(connections)), rotation)
        net_file = build(plain, workdir, self.name)
        net = read_net(net_file)
        (x1, y1), (x2, y2) = (net.getNode(n).getCoord()[:2] for n in ("M1", "M2"))
        centre = InterestCentre(
            round((x1 + x2) / 2, 2), round((y1 + y2) / 2, 2), round(accel / 2 + 60.0, 1), "merge", "M1"
        )
        params: dict[str, object] = {
            "rotation_deg": rotation,
            "lanes": lanes,
            "speed_kmh": speed,
            "ramp_speed_kmh": ramp_speed,
            "upstream_m": upstream,
            "accel_lane_m": accel,
            "ramp_length_m": ramp_length,
            "ramp_angle_deg": ramp_angle,
            "off_ramp": off_ramp,
            "off_ramp_gap_m": gap if off_ramp else 0.0,
            "decel_lane_m": decel if off_ramp else 0.0,
            "downstream_m": downstream,
        }
        return BuiltNetwork(self.name, net_file, (centre,), params, pedestrians=False, bicycles=False)
