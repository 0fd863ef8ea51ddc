"""What the detector's parts share: the `Pair` record they produce and the `ScenePart` base that gives each part
its scene's arrays (docs/interdrive.md, 'Interaction labels')."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from langtraj.interdrive.detector.scene import SceneGeometry


@dataclass(frozen=True)
class Pair:
    """Agent index `agent` does something to agent index `other` over [start, end)."""

    agent: int
    other: int
    start: int
    end: int


class ScenePart:
    """One group of per-scene quantities (paths, lanes, yields, ...), each computed once on first use, over the
    arrays of its `SceneGeometry` (shared, not copied)."""

    def __init__(self, scene: SceneGeometry):
        self.scene = scene
        self.scenario, self.config, self.map_index = scene.scenario, scene.config, scene.map_index
        self.xy, self.heading, self.speed, self.accel = scene.xy, scene.heading, scene.speed, scene.accel
        self.length, self.valid = scene.length, scene.valid
        self.types, self.ids, self.movers = scene.types, scene.ids, scene.movers

    @property
    def num_steps(self) -> int:
        return self.scene.num_steps

    @property
    def static(self) -> np.ndarray:
        return self.scene.static

    @property
    def parked(self) -> np.ndarray:
        return self.scene.parked
