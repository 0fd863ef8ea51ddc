"""The record types of one SUMO run, shared by the runner, the track builder, the intent controller and the
event extraction: what SUMO reported (`RawTrack`, `LaneChangeRecord`) and the clean tracks built from it
(`Track`). They live apart so that the intent controller, which the runner drives, needs neither module.

See docs/data.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from langtraj.scenario.types import AgentType


@dataclass
class RawTrack:
    """What SUMO reported for one agent at each step it existed (front position, SUMO angle)."""

    sumo_id: str
    agent_type: AgentType
    vclass: str
    vtype: str
    length: float
    width: float
    height: float
    steps: list[int] = field(default_factory=list)
    rows: list[tuple[float, float, float, float]] = field(default_factory=list)  # front x, y, SUMO angle, speed
    lanes: list[int] = field(default_factory=list)  # interned lane (vehicles) or lane-of-edge (persons) ids
    leaders: list[str] = field(default_factory=list)
    gaps: list[float] = field(default_factory=list)


@dataclass(frozen=True)
class LaneChangeRecord:
    """One row of SUMO's lane-change output (`changeStarted`, `change` or `changeEnded`)."""

    tag: str
    sumo_id: str
    step: int
    from_lane: str
    to_lane: str
    direction: int
    reason: str


@dataclass(frozen=True, eq=False)
class Track:
    """One agent over global steps [start, start + n): centres, headings, speeds and lanes.

    `lane` indexes the simulation's interned lane names (-1 at invalid steps); `leader` is the track id of
    the vehicle ahead within range (-1 when none) and `gap` the bumper-to-bumper distance to it.
    """

    track_id: int
    sumo_id: str
    agent_type: AgentType
    vtype: str
    size: tuple[float, float, float]
    start: int
    xy: np.ndarray  # float64 [n, 2]
    heading: np.ndarray  # float64 [n]
    speed: np.ndarray  # float64 [n]
    valid: np.ndarray  # bool [n]
    lane: np.ndarray  # int32 [n]
    leader: np.ndarray  # int64 [n]
    gap: np.ndarray  # float32 [n]

    @property
    def stop(self) -> int:
        """One past the last global step of the track."""
        return self.start + len(self.valid)

    def local(self, step: int) -> int:
        """Index into the arrays of global `step` (which must lie in [start, stop))."""
        return step - self.start
