"""The records map queries return and both labelers share: `LaneMatch`, `LaneChange`, and the `LanePosition` and
`Side` literals (docs/interdrive.md, 'Single-agent labels')."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

LanePosition = Literal["leftmost", "middle", "rightmost", "single", "unknown"]
Side = Literal["left", "right"]


@dataclass(frozen=True, eq=False)
class LaneMatch:
    """Best lane of each query point; `lane` is an index into `MapIndex.lane_ids`, -1 where none matched."""

    lane: np.ndarray  # int64 [N]
    distance: np.ndarray  # float64 [N], distance to the centerline, inf where none
    lateral: np.ndarray  # float64 [N], signed offset from the centerline (left positive), nan where none
    station: np.ndarray  # float64 [N], arc length along the lane, nan where none
    heading: np.ndarray  # float64 [N], centerline heading there, nan where none

    @property
    def matched(self) -> np.ndarray:
        return self.lane >= 0


@dataclass(frozen=True)
class LaneChange:
    """Agent index `agent` switches from lane `from_lane` to neighbour lane `to_lane` (map feature ids, -1 where
    unknown) at window step `switch`, over window steps [start, end).

    The detector fills only these; the heuristic labeler also the `side` of the new lane, the `lateral`
    displacement across the lanes (m, left positive) and the lane positions left and entered."""

    agent: int
    from_lane: int
    to_lane: int
    switch: int
    start: int
    end: int
    side: Side | None = None
    lateral: float | None = None
    from_position: LanePosition = "unknown"
    to_position: LanePosition = "unknown"
