"""Zebra kind: a straight road with a mid-block zebra crossing where pedestrians have priority. See docs/data.md."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from langtraj.synth.kinds.xmlfiles import (
    KMH,
    Crossing,
    Node,
    PlainNetwork,
    build,
    chance,
    junction_centres,
    read_net,
    rotate,
    two_way,
    uniform,
)
from langtraj.synth.network import BuiltNetwork, NetworkKind, register_kind


@register_kind
class Zebra(NetworkKind):
    """Two- or four-lane road with a priority crossing at a mid-block node."""

    name = "zebra"
    description = "straight 2- or 4-lane road with a mid-block zebra crossing (pedestrians have priority)"

    def build(self, rng: np.random.Generator, workdir: Path) -> BuiltNetwork:
        """Draw lengths, lanes, speed, crossing width and bike lanes; build with netconvert."""
        rotation = uniform(rng, 0.0, 360.0)
        lanes = 2 if chance(rng, 0.3) else 1
        speed = uniform(rng, 30.0, 50.0)
        west, east = uniform(rng, 150.0, 220.0), uniform(rng, 150.0, 220.0)
        sidewalk, width = uniform(rng, 2.0, 3.0, 2), uniform(rng, 3.0, 5.0)
        bike_lane = uniform(rng, 1.5, 2.0, 2) if chance(rng, 0.4) else 0.0
        # Straight through M: a bend shrinks the junction so the crossing no longer lies inside it.
        nodes = (Node("W", -west, 0.0), Node("M", 0.0, 0.0), Node("E", east, 0.0))
        side = {"sidewalk": sidewalk, "bike_lane": bike_lane}
        edges = (*two_way("W", "M", lanes, speed * KMH, **side), *two_way("M", "E", lanes, speed * KMH, **side))
        crossing = Crossing("M", ("M_E", "E_M"), priority=True, width=width)
        plain = rotate(PlainNetwork(nodes, edges, crossings=(crossing,)), rotation)
        net_file = build(plain, workdir, self.name)
        centres = junction_centres(read_net(net_file), ["M"], 40.0, "crosswalk")
        params: dict[str, object] = {
            "rotation_deg": rotation,
            "lanes_per_direction": lanes,
            "speed_kmh": speed,
            "west_m": west,
            "east_m": east,
            "sidewalk_m": sidewalk,
            "crossing_width_m": width,
            "bike_lane_m": bike_lane,
        }
        return BuiltNetwork(self.name, net_file, centres, params, pedestrians=True, bicycles=bike_lane > 0)
