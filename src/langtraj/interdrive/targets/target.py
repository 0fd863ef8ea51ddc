"""A behaviour's target: where it takes an agent on the map (`BehaviourTarget`), or why the scene gives none
(`TargetUnavailable`, with its `Status`). See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from langtraj.errors import InputError
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour, Side
from langtraj.polylines import point_at
from langtraj.roads.routes import ROUTE_SPACING

Status = Literal["feasible", "infeasible", "undecided"]


@dataclass(frozen=True)
class BehaviourTarget:
    """Where `behaviour` takes agent `track_id` (world frame, metres, seconds from the current step).

    `path` [N, 2] is the centreline to drive along (empty when the map gives none); `station_of_goal` is how far
    along it the agent must get (a turn: past the junction's exit) or must not pass (a stop, a pull-over, a
    yield: the stop or conflict point). `speed` is a target speed where the behaviour sets one (0: it stops). A pair
    behaviour names `other_id`, the `conflict` point [2] of the two paths (None when they do not cross) and the
    `other_eta` (s) at which the other agent reaches it at its current speed. `reason` says how the target was
    derived."""

    track_id: int
    behaviour: Behaviour
    path: np.ndarray
    reason: str
    station_of_goal: float | None = None
    speed: float | None = None
    other_id: int | None = None
    conflict: np.ndarray | None = None
    other_eta: float | None = None
    current_speed: float = 0.0
    other_speed: float | None = None
    side: Side | None = None
    """The side it moves across to (a lane change, a cut-in), where there is one."""
    settled_s: float | None = None
    """When the agent must be at `station_of_goal` (s), where the target times it (a cut-in, a tailgate, a braking
    lead at rest)."""
    deceleration: float | None = None
    """How hard it brakes (m/s^2), where the target says (a braking lead)."""
    lead_m: float | None = None
    """How far the agent's centre is ahead of the other's along the path once settled (m), where the target says (a
    cut-in, an overtake and cut-in: the gap and the half lengths), so that steering can keep it relative to where
    the other actually drives."""
    own_lane: np.ndarray | None = None
    """The agent's own lane ahead [M, 2] (world frame), where the target's `path` leaves it (a cut-in: where it keeps
    to until it moves across)."""
    new_lane: np.ndarray | None = None
    """The lane it moves into [M, 2] (world frame) from beside the agent on (a cut-in, an overtake and cut-in), where
    the target's `path` leads into one: what a scripted change follows (`behaviours.scripts`)."""
    other_gap_m: float | None = None
    """The bumper gap to the other agent along the lane at the current step (m), where the target reads it (a braking
    lead: its follower's gap)."""
    starts_s: float | None = None
    """When the agent sets off (s), where the target has it wait first (a pull-out waiting for its moment)."""
    stop_line_m: float | None = None
    """How far along the path a stop line it passes is (m), where the target runs one (a red-light run): a scripted
    runner early for its moment stands short of it (`behaviours.scripts.Crossing`)."""
    closes_to_m: float | None = None
    """The bumper gap (m) the agent eases off to let the other, behind it, come within, where it is placed for a
    trigger on that gap (a braking lead before "when @ego is within 20 m of @4": `BehaviourKind.placed`)."""
    joins_m: float | None = None
    """How far along the path it joins its new lane (m), where the target changes lanes (a lane change: where its
    lead-in meets the lane), so that what is asked after the change lies past it (`stop_after`)."""

    @property
    def stop(self) -> bool:
        """Whether the agent must come to rest at `station_of_goal`."""
        return self.speed == 0.0

    @property
    def first(self) -> bool | None:
        """Whether the agent passes the conflict point first (None for a single-agent behaviour)."""
        return None if self.other_id is None else BEHAVIOURS[self.behaviour].first

    @property
    def goal_point(self) -> np.ndarray | None:
        """The point of `path` at `station_of_goal` [2] (None without one)."""
        if self.station_of_goal is None or len(self.path) < 2:
            return None
        return point_at(self.path, self.station_of_goal)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready: the path every 2 m and the points rounded to centimetres (world frame)."""
        goal = self.goal_point
        return {
            "track_id": self.track_id,
            "behaviour": self.behaviour.value,
            "reason": self.reason,
            "path": np.round(self.path[:: max(1, round(2.0 / ROUTE_SPACING))], 2).tolist(),
            "goal": None if goal is None else [round(float(v), 2) for v in goal],
            "stop": self.stop,
            "speed": self.speed,
            "other_id": self.other_id,
            "conflict": None if self.conflict is None else [round(float(v), 2) for v in self.conflict],
            "first": self.first,
        }


class TargetUnavailable(InputError):
    """The map gives no target for the behaviour: it is "infeasible" there (the map rules it out) or "undecided"
    (the map lacks what it takes to tell); `reason` says why, without naming the agent."""

    def __init__(self, track_id: int, behaviour: Behaviour, status: Status, reason: str):
        self.track_id, self.behaviour, self.status, self.reason = track_id, behaviour, status, reason
        super().__init__(f"@{track_id} cannot {BEHAVIOURS[behaviour].manoeuvre}: {reason}", where="target")
