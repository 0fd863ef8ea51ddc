"""A small constructed scene for the rendering tests, and where a world point lands in a frame."""

from __future__ import annotations

import numpy as np
from matplotlib.colors import to_rgb

from langtraj.scenario.model import Agents, MapFeature, RoadMap, Scenario, TrafficLights
from langtraj.scenario.types import AgentType, MapFeatureType, TrafficLightState
from langtraj.viz import RenderConfig, TopDownRenderer

SMALL = RenderConfig(size_px=160, trail_steps=5)
NUM_STEPS = 12
SDC_ID = 100


def make_scenario(num_steps: int = NUM_STEPS) -> Scenario:
    """A small crossing: the SDC and two vehicles drive along x, a pedestrian, a cyclist and an
    'other' agent move across; one lane, road line, road edge, crosswalk, stop sign and signal."""
    t = np.arange(num_steps) * 0.1
    # (id, type, start xy, velocity xy, length, width)
    tracks = [
        (SDC_ID, AgentType.VEHICLE, (-20.0, 0.0), (8.0, 0.0), 5.0, 2.4),
        (101, AgentType.VEHICLE, (-5.0, 4.0), (6.0, 0.0), 4.5, 2.0),
        (102, AgentType.VEHICLE, (15.0, -4.0), (-5.0, 0.0), 4.5, 2.0),
        (200, AgentType.PEDESTRIAN, (8.0, -10.0), (0.0, 1.4), 0.6, 0.6),
        (300, AgentType.CYCLIST, (-10.0, 10.0), (0.0, -4.0), 1.8, 0.7),
        (400, AgentType.OTHER, (20.0, 10.0), (-1.0, -1.0), 1.0, 1.0),
    ]
    states = np.zeros((len(tracks), num_steps, 9), np.float32)
    for a, (_, _, (x, y), (vx, vy), length, width) in enumerate(tracks):
        states[a, :, 0] = x + vx * t
        states[a, :, 1] = y + vy * t
        states[a, :, 3] = np.arctan2(vy, vx)
        states[a, :, 4], states[a, :, 5] = vx, vy
        states[a, :, 6], states[a, :, 7], states[a, :, 8] = length, width, 1.5
    valid = np.ones((len(tracks), num_steps), bool)
    valid[5, : num_steps // 2] = False  # the 'other' agent appears halfway
    agents = Agents(ids=[tr[0] for tr in tracks], types=[int(tr[1]) for tr in tracks], states=states, valid=valid)
    xs = np.linspace(-40, 40, 17)
    features = [
        MapFeature(1, MapFeatureType.LANE_SURFACE_STREET, np.stack([xs, np.zeros_like(xs)], 1)),
        MapFeature(2, MapFeatureType.LANE_BIKE_LANE, np.stack([xs, np.full_like(xs, -7.0)], 1)),
        MapFeature(3, MapFeatureType.ROAD_LINE_BROKEN_SINGLE_WHITE, np.stack([xs, np.full_like(xs, 2.0)], 1)),
        MapFeature(4, MapFeatureType.ROAD_LINE_SOLID_DOUBLE_YELLOW, np.stack([xs, np.full_like(xs, -2.0)], 1)),
        MapFeature(5, MapFeatureType.ROAD_EDGE_BOUNDARY, np.stack([xs, np.full_like(xs, 6.0)], 1)),
        MapFeature(6, MapFeatureType.CROSSWALK, [(5, -6), (11, -6), (11, 6), (5, 6)]),
        MapFeature(7, MapFeatureType.SPEED_BUMP, [(-30, -1), (-29, -1), (-29, 1), (-30, 1)]),
        MapFeature(8, MapFeatureType.DRIVEWAY, [(-15, 6), (-10, 6), (-10, 12), (-15, 12)]),
        MapFeature(9, MapFeatureType.STOP_SIGN, [(4.0, 3.0, 0.0)], controlled_lanes=(1,)),
    ]
    lights = TrafficLights(
        lane_ids=[1],
        states=np.full((num_steps, 1), int(TrafficLightState.STOP)),
        valid=np.ones((num_steps, 1), bool),
        stop_points=[(3.0, 0.0, 0.0)],
    )
    return Scenario("test-scene", t, 3, 0, agents, RoadMap(features), lights)


def pixel(renderer: TopDownRenderer, step: int, xy: tuple[float, float]) -> tuple[int, int]:
    """(row, col) of a world point in the frame of `step`."""
    x0, x1, y0, y1 = renderer.camera.limits(step)
    size = renderer.config.size_px
    return int((y1 - xy[1]) / (y1 - y0) * size), int((xy[0] - x0) / (x1 - x0) * size)


def near_colour(image: np.ndarray, row: int, col: int, colour: str, radius: int = 2, tol: int = 30) -> bool:
    target = np.array(to_rgb(colour)) * 255
    patch = image[max(row - radius, 0) : row + radius + 1, max(col - radius, 0) : col + radius + 1]
    return bool((np.abs(patch.astype(float) - target).max(axis=-1) <= tol).any())
