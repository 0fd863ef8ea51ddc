"""`SceneArrays`: one scene's agent arrays and who stands all window, which every part of the detector reads
(shared, not copied; docs/interdrive.md, 'Interaction labels')."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from langtraj.interdrive.detector.config import MOVERS, DetectorConfig
from langtraj.roads import LaneMatch, MapIndex
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import StateField


@dataclass(frozen=True, eq=False)
class SceneArrays:
    """The scene, the thresholds, the map index and the agents' per-step arrays; who stands (`is_static`,
    `is_parked`) is computed per agent on first use, and for every agent at once by `static` and `parked`."""

    scenario: Scenario
    config: DetectorConfig
    map_index: MapIndex
    xy: np.ndarray  # float64 [A, T, 2]
    heading: np.ndarray  # float64 [A, T]
    speed: np.ndarray  # float64 [A, T]
    accel: np.ndarray  # float64 [A, T], the gradient of `speed`
    length: np.ndarray  # float64 [A, T]
    valid: np.ndarray  # bool [A, T]
    types: np.ndarray  # [A]
    ids: np.ndarray  # [A]
    movers: np.ndarray  # bool [A], vehicles and cyclists (`MOVERS`)

    @classmethod
    def of(cls, scenario: Scenario, config: DetectorConfig, map_index: MapIndex) -> SceneArrays:
        """The arrays of `scenario`'s agents."""
        agents = scenario.agents
        speed = agents.speed.astype(np.float64)
        types = agents.types
        steps = agents.num_steps
        return cls(
            scenario=scenario,
            config=config,
            map_index=map_index,
            xy=agents.xy.astype(np.float64),
            heading=agents.heading.astype(np.float64),
            speed=speed,
            accel=np.gradient(speed, STEP_SECONDS, axis=1) if steps > 1 else np.zeros_like(speed),
            length=agents.states[..., StateField.LENGTH].astype(np.float64),
            valid=agents.valid,
            types=types,
            ids=agents.ids,
            movers=np.isin(types, MOVERS),
        )

    @property
    def num_steps(self) -> int:
        return self.scenario.num_steps

    def match_lanes(self, xy: np.ndarray, heading: np.ndarray, exclude_junctions: bool) -> LaneMatch:
        """The lane of each point: the nearest centreline within `lane_match_distance` among lanes (of any kind)
        heading within `lane_match_heading`."""
        cfg = self.config
        return self.map_index.match_lanes(
            xy, heading, radius=cfg.lane_match_distance, max_heading_diff=cfg.lane_match_heading,
            heading_weight=0.0, drivable_only=False, exclude_junctions=exclude_junctions,
        )  # fmt: skip

    # ------------------------------------------------------------ standing agents
    @cached_property
    def static(self) -> np.ndarray:
        """[A]: `is_static` of every agent."""
        return np.array([self.is_static(a) for a in range(len(self.ids))], bool)

    @cached_property
    def parked(self) -> np.ndarray:
        """[A]: `is_parked` of every agent."""
        return np.array([self.is_parked(a) for a in range(len(self.ids))], bool)

    @cached_property
    def _standing(self) -> dict[tuple[str, int], bool]:
        """`is_static` and `is_parked` of the agents asked about so far."""
        return {}

    def is_static(self, a: int) -> bool:
        """Agent `a` stands over the whole window, history included: its valid positions span at most
        `static_displacement` (a parked car, or one waiting all window long)."""
        key = ("static", a)
        if key not in self._standing:
            pts = self.xy[a, self.valid[a]]
            span = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) if len(pts) else np.inf
            self._standing[key] = span <= self.config.static_displacement
        return self._standing[key]

    def is_parked(self, a: int) -> bool:
        """Agent `a` is static and on no map lane at any step (the road side, a parking lot); every static agent
        where the map has no lanes. The road-side test is `MapIndex.parked_decision` on the agent's lane match at
        every valid step; undecided counts as parked."""
        key = ("parked", a)
        if key not in self._standing:
            parked = self.is_static(a)
            if parked:
                steps = self.valid[a]
                match = self.match_lanes(self.xy[a, steps], self.heading[a, steps], exclude_junctions=False)
                parked = self.map_index.parked_decision(match, self.xy[a, steps])[0] is not False
            self._standing[key] = parked
        return self._standing[key]
