"""`SceneGeometry`: the per-scene quantities the detector's rules share (docs/interdrive.md, 'Interaction labels').

It holds the agents' arrays and who stands all window; the rest lives in its parts, each computed once on first
use: `paths` (paths, leaders, following), `lanes` (lane matches, lane leaders, roundabouts), `changes` (lane
changes, merges, overtakes), `yields` (held vehicles, yields at conflict points) and `crossings` (pedestrians and
crosswalks).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import numpy as np

from langtraj.interdrive.detector.config import MOVERS, DetectorConfig
from langtraj.interdrive.detector.crosswalks import CrosswalkGeometry
from langtraj.interdrive.detector.lane_changes import LaneChangeGeometry
from langtraj.interdrive.detector.lanes import LaneGeometry
from langtraj.interdrive.detector.paths import PathGeometry
from langtraj.interdrive.detector.yields import YieldGeometry
from langtraj.interdrive.labels import AgentLabel
from langtraj.interdrive.mapindex import MapIndex
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import StateField


class SceneGeometry:
    """Per-scene quantities the rules share, each computed once on first use."""

    def __init__(
        self,
        scenario: Scenario,
        agent_labels: Sequence[AgentLabel],
        config: DetectorConfig,
        map_index: MapIndex | None = None,
    ):
        self.scenario = scenario
        self.agent_labels = tuple(agent_labels)
        self.config = config
        self.map_index = map_index or MapIndex.build(scenario.road_map)
        agents = scenario.agents
        self.xy = agents.xy.astype(np.float64)
        self.heading = agents.heading.astype(np.float64)
        self.speed = agents.speed.astype(np.float64)
        self.valid = agents.valid
        self.length = agents.states[..., StateField.LENGTH].astype(np.float64)
        self.types = agents.types
        self.ids = agents.ids
        self.movers = np.isin(self.types, MOVERS)
        steps = agents.num_steps
        self.accel = np.gradient(self.speed, STEP_SECONDS, axis=1) if steps > 1 else np.zeros_like(self.speed)
        # the parts compute nothing until asked
        self.paths = PathGeometry(self)
        self.lanes = LaneGeometry(self)
        self.changes = LaneChangeGeometry(self)
        self.yields = YieldGeometry(self)
        self.crossings = CrosswalkGeometry(self)

    @property
    def num_steps(self) -> int:
        return self.scenario.num_steps

    # ------------------------------------------------------------ standing agents
    @cached_property
    def static(self) -> np.ndarray:
        """[A]: the agent stands over the whole window, history included: its valid positions span at most
        `static_displacement` (a parked car, or one waiting all window long)."""
        out = np.zeros(len(self.ids), bool)
        for a in range(len(self.ids)):
            pts = self.xy[a, self.valid[a]]
            if len(pts):
                out[a] = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) <= self.config.static_displacement
        return out

    @cached_property
    def parked(self) -> np.ndarray:
        """[A]: static and on no map lane at any step (the road side, a parking lot); every static agent where the
        map has no lanes. The road-side test is `MapIndex.parked_decision` on the agent's lane match at every
        valid step; undecided counts as parked."""
        out = self.static.copy()
        for a in np.flatnonzero(out).tolist():
            steps = self.valid[a]
            match = self.lanes.match(self.xy[a, steps], self.heading[a, steps], exclude_junctions=False)
            out[a] = self.map_index.parked_decision(match, self.xy[a, steps])[0] is not False
        return out
