"""What the detector's parts share: the `Pair` record they produce and the `ScenePart` base that gives each part
its scene's `SceneArrays` (docs/interdrive.md, 'Interaction labels')."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from langtraj.interdrive.detector.arrays import SceneArrays


@dataclass(frozen=True)
class Pair:
    """Agent index `agent` does something to agent index `other` over [start, end)."""

    agent: int
    other: int
    start: int
    end: int


class ScenePart:
    """One group of per-scene quantities (paths, lanes, yields, ...), each computed once on first use, over the
    scene's `SceneArrays` (shared, not copied). A part that reads another is given it when built (see
    `SceneGeometry`)."""

    def __init__(self, arrays: SceneArrays):
        self.arrays = arrays
        self.scenario, self.config, self.map_index = arrays.scenario, arrays.config, arrays.map_index
        self.xy, self.heading, self.speed, self.accel = arrays.xy, arrays.heading, arrays.speed, arrays.accel
        self.length, self.valid = arrays.length, arrays.valid
        self.types, self.ids, self.movers = arrays.types, arrays.ids, arrays.movers

    @property
    def num_steps(self) -> int:
        return self.arrays.num_steps

    @property
    def static(self) -> np.ndarray:
        return self.arrays.static

    @property
    def parked(self) -> np.ndarray:
        return self.arrays.parked
