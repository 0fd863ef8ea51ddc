"""What happened to the ego at a step (docs/testing.md, 'Step info'): collision and with whom, whether the ego
caused it, off-road, time to collision with the agent ahead, with the WOSAC metrics' own box geometry
(`metrics.interaction`, `metrics.road`), so a suite and the realism scores agree on what a collision is."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.metrics.features import COLLISION_THRESHOLD, OFFROAD_THRESHOLD
from langtraj.metrics.interaction import MAX_TTC, pair_signed_distance, time_to_collision
from langtraj.metrics.road import RoadEdgeIndex, distance_to_road_edge
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import StateField

AT_FAULT_MIN_SPEED = 0.5
"""An ego slower than this (m/s) does not cause a collision."""
AT_FAULT_CONE = math.radians(60.0)
"""The ego causes a collision with an agent whose centre lies within this angle of its heading (its front)."""


@dataclass(frozen=True)
class StepEvents:
    """The ego's safety figures at one step."""

    collided_with: tuple[int, ...]  # track ids whose boxes overlap the ego's
    at_fault: bool  # a collision the ego causes: it moves and the other is in front of it
    offroad: bool
    ttc: float  # s until the ego reaches the agent it follows at constant speeds (`MAX_TTC` when none)
    min_distance: float  # m between the ego's box and the nearest other box (negative: overlap)

    @property
    def collision(self) -> bool:
        return bool(self.collided_with)


class EventJudge:
    """Judges the ego (scenario row `ego`) against every other valid agent and the road edges of `scenario`
    (`edges`: `metrics.road.road_edge_index` of them, None without any)."""

    def __init__(self, scenario: Scenario, ego: int, edges: RoadEdgeIndex | None):
        self.ego = ego
        self.ids = scenario.agents.ids.astype(np.int64)
        self.edges = edges

    def judge(self, states: np.ndarray, valid: np.ndarray) -> StepEvents:
        """The figures from every agent's state [A, 9] and validity [A] at one step."""
        s = states.astype(np.float64)
        x, y, heading = s[:, StateField.X], s[:, StateField.Y], s[:, StateField.HEADING]
        length, width = s[:, StateField.LENGTH], s[:, StateField.WIDTH]
        speed = np.hypot(s[:, StateField.VX], s[:, StateField.VY])

        def grid(v: np.ndarray) -> np.ndarray:  # [1 rollout, A, 1 step]
            return v[None, :, None]

        e = self.ego
        ttc = time_to_collision(
            grid(x), grid(y), grid(heading), grid(length), grid(width), grid(speed), grid(valid), np.array([e])
        )
        others = np.flatnonzero(valid)
        others = others[others != e]
        gap = pair_signed_distance(x[e], y[e], heading[e], length[e], width[e],
                                   x[others], y[others], heading[others], length[others], width[others])  # fmt: skip
        hit = others[gap < COLLISION_THRESHOLD]
        at_fault = False
        if len(hit) and speed[e] > AT_FAULT_MIN_SPEED:
            bearing = np.arctan2(y[hit] - y[e], x[hit] - x[e]) - heading[e]
            at_fault = bool((np.abs(wrap_angle(bearing)) < AT_FAULT_CONE).any())
        offroad = False
        if self.edges is not None:
            one = s[e : e + 1]
            dist = distance_to_road_edge(
                self.edges, x[e : e + 1], y[e : e + 1], one[:, StateField.Z], heading[e : e + 1], length[e : e + 1],
                width[e : e + 1], one[:, StateField.HEIGHT], np.ones(1, bool),
            )  # fmt: skip
            offroad = bool(dist[0] > OFFROAD_THRESHOLD)
        return StepEvents(
            collided_with=tuple(int(i) for i in self.ids[hit]),
            at_fault=at_fault,
            offroad=offroad,
            ttc=float(min(ttc[0, 0, 0], MAX_TTC)),
            min_distance=float(gap.min()) if len(gap) else math.inf,
        )
