"""`SceneGeometry`: the per-scene quantities the detector's rules share (docs/interdrive.md, 'Interaction labels').

It holds the agents' arrays and who stands all window (`SceneArrays`, in `arrays`); the rest lives in its parts,
each computed once on first use and built here in dependency order, each given the parts it reads: `paths` (paths,
leaders, following), `lanes` (lane matches, lane leaders, roundabouts), `changes` (lane changes, merges,
overtakes), `yields` (held vehicles, yields at conflict points), `crossings` (pedestrians and crosswalks),
`red_lights` (red lights run across another's path) and `pull_outs` (vehicles pulling out in front of another).
"""

from __future__ import annotations

from collections.abc import Sequence

from langtraj.interdrive.detector.arrays import SceneArrays
from langtraj.interdrive.detector.config import DetectorConfig
from langtraj.interdrive.detector.crosswalks import CrosswalkGeometry
from langtraj.interdrive.detector.lane_changes import LaneChangeGeometry
from langtraj.interdrive.detector.lanes import LaneGeometry
from langtraj.interdrive.detector.parts import ScenePart
from langtraj.interdrive.detector.paths import PathGeometry
from langtraj.interdrive.detector.pull_outs import PullOutGeometry
from langtraj.interdrive.detector.red_lights import RedLightGeometry
from langtraj.interdrive.detector.yields import YieldGeometry
from langtraj.interdrive.labels import AgentLabel
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario


class SceneGeometry(ScenePart):
    """Per-scene quantities the rules share, each computed once on first use: the arrays (as every part has them)
    and the parts."""

    def __init__(
        self,
        scenario: Scenario,
        agent_labels: Sequence[AgentLabel],
        config: DetectorConfig,
        map_index: MapIndex | None = None,
    ):
        super().__init__(SceneArrays.of(scenario, config, map_index or MapIndex.build(scenario.road_map)))
        self.agent_labels = tuple(agent_labels)
        arrays = self.arrays
        # the parts compute nothing until asked
        self.paths = PathGeometry(arrays)
        self.lanes = LaneGeometry(arrays, self.paths)
        self.changes = LaneChangeGeometry(arrays, self.lanes, self.agent_labels)
        self.yields = YieldGeometry(arrays, self.paths, self.lanes)
        self.crossings = CrosswalkGeometry(arrays, self.yields)
        self.red_lights = RedLightGeometry(arrays, self.yields)
        self.pull_outs = PullOutGeometry(arrays, self.lanes)
