"""`HeuristicConfig`: every threshold of the heuristic single-agent labeler (docs/interdrive.md, 'Single-agent
labels')."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from langtraj.roads.position import LANE_MATCH_MAX_HEADING, LANE_MATCH_RADIUS


@dataclass(frozen=True)
class HeuristicConfig:
    """Every threshold of the heuristic labeler; units: m, s, m/s, m/s^2, rad."""

    min_future_fraction: float = 0.5
    """Share of the future steps an agent must be valid on to be labelled at all."""
    position_smoothing_s: float = 0.5
    """Moving-average window over positions before differencing (s)."""
    speed_smoothing_s: float = 0.5
    """Moving-average window over speeds (s)."""
    accel_smoothing_s: float = 0.9
    """Moving-average window over accelerations (s)."""
    static_speed: float = 0.5
    """A vehicle at or below this speed is stopped (m/s)."""
    slow_speed: float = 3.0
    """A moving vehicle at or below this speed moves slowly (m/s)."""
    vru_static_speed: float = 0.4
    """A pedestrian or cyclist at or below this speed is static (m/s)."""
    accel_threshold: float = 0.4
    """Acceleration at or beyond which a vehicle speeds up / slows down; below it, constant speed (m/s^2)."""
    min_speed_change: float = 1.0
    """Least speed change over a speeding-up or slowing-down span (m/s); smaller changes count as constant."""
    min_duration_s: float = 1.0
    """Shortest span of a speed, static, moving, crossing-street or walking-along label (s)."""
    slow_min_duration_s: float = 2.0
    """Shortest span of `moving_slowly` (s)."""
    parked_max_displacement: float = 1.0
    """A parked vehicle moves at most this far over all its valid steps, history included (m)."""
    parked_min_lane_offset: float = 1.5
    """A static vehicle this far or farther from the nearest lane centre is at the road side (m)."""
    parked_max_edge_distance: float = 1.5
    """A static vehicle whose centre is this close to a road edge is at the kerb (m)."""
    parked_queue_distance: float = 30.0
    """A static vehicle on a lane centre at most this far before a junction along its lane is queued, not parked
    (m; needs lane connectivity)."""
    turn_min_angle: float = math.radians(40.0)
    """Net heading change over the moving future that makes a turn (rad); positive is left. A turn at a skewed
    junction can change the heading by only about 45 degrees, and a window may not hold all of it."""
    straight_max_angle: float = math.radians(35.0)
    """Largest net heading change of a vehicle going straight (rad): roads that meet at an angle, or bend
    near a junction, make a through movement turn by up to about 35 degrees."""
    turn_span_fraction: float = 0.15
    """A turn's span runs from this fraction of its heading change to one minus it."""
    min_path_length: float = 5.0
    """Shortest future path of a vehicle given a turn / straight label (m)."""
    lane_match_radius: float = LANE_MATCH_RADIUS
    """Largest distance from a vehicle to the centerline of its matched lane (m)."""
    lane_match_max_heading: float = LANE_MATCH_MAX_HEADING
    """Largest heading disagreement between a vehicle and its matched lane (rad)."""
    off_road_distance: float = 4.0
    """A vehicle farther than this from every drivable lane centerline is off the main roads (m)."""
    junction_min_duration_s: float = 0.5
    """Shortest stay on junction lanes that counts, and longest gap bridged inside one (s)."""
    approach_lookahead: float = 40.0
    """A vehicle within this distance of a junction ahead (along its lanes or its path) approaches it (m)."""
    lane_min_run_s: float = 0.5
    """A matched lane must hold this long to count; shorter flickers join the lane before (s)."""
    lane_change_min_lateral: float = 2.0
    """Least lateral displacement, across the lane, that confirms a lane change (m)."""
    lane_change_settle_offset: float = 0.5
    """A lane change ends where the vehicle is first within this of its new lane centre (m)."""
    lane_change_start_offset: float = 0.2
    """A lane change starts at the last step where the vehicle is within this of its least offset toward the
    new lane over the `lane_change_max_duration_s` before the switch (that least offset counted as between
    the lane centre and `lane_change_settle_offset`): where its sideways motion begins, before its heading
    turns (m)."""
    lane_change_max_duration_s: float = 5.0
    """How far before the switch a lane change's start is looked for (s)."""
    lane_change_require_settled: bool = True
    """Leave out a lane change still under way at the agent's last step: not yet within
    `lane_change_settle_offset` of the new lane's centre and still moving toward it by more than
    `lane_change_start_offset` over the last `lane_change_settle_s` (the manoeuvre must end in the scene)."""
    lane_change_settle_s: float = 1.0
    """See `lane_change_require_settled` (s)."""
    pull_over_min_stop_s: float = 2.0
    """Shortest stop (at or below `static_speed`) that ends a pull-over (s)."""
    pull_over_lookback_s: float = 8.0
    """How far before the stop (and no earlier than the current step or the end of an earlier stop) the sideways
    motion of a pull-over is looked for (s)."""
    pull_over_min_lateral: float = 0.5
    """Least sideways displacement toward the road side, across the lane, before or during a stop that makes a
    pull-over (m; SUMO's pull-overs to the kerb of a 3.2 m lane move 0.6 m)."""
    pull_over_min_lane_offset: float = 0.4
    """Least offset of a pulled-over vehicle's stop from its lane's centre, toward the road side: it stops at the
    edge of its lane or beyond it, not on the centre as in a queue (m)."""
    pull_over_max_edge_distance: float = 3.0
    """Largest distance from a pulled-over vehicle's centre to a road edge where the map has road edges (m; a
    bike lane or a parking strip may lie between the kerb and the road edge)."""
    pull_over_junction_distance: float = 15.0
    """A stop on a junction lane or at most this far before one along its lane is a stop at the junction, not a
    pull-over (m; needs lane connectivity)."""
    pull_over_start_offset: float = 0.2
    """A pull-over starts at the last step within this of the vehicle's offset farthest from the road side before
    its stop: where its sideways motion begins (m)."""
    lane_position_max_offset: float = 1.5
    """Largest distance from the lane centre at which a vehicle gets a lane position (m)."""
    crossing_lane_radius: float = 2.0
    """A pedestrian or cyclist this close to a lane centerline, moving across it, crosses the street (m)."""
    crossing_min_angle: float = math.radians(50.0)
    """Least angle between VRU motion and the lane to count as crossing it (rad, folded to [0, pi/2])."""
    along_road_distance: float = 7.0
    """A VRU within this distance of a lane centerline is by the road (m)."""
    along_max_angle: float = math.radians(30.0)
    """Largest angle between VRU motion and the nearest lane to count as walking along it (rad, folded)."""
    infer_neighbors: bool = False
    """Infer lane neighbours from geometry when the map has none (otherwise lane positions are undecided)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, bool) and not value >= 0:
                raise ValueError(f"HeuristicConfig.{f.name} must be >= 0, got {value!r}")
        if not 0 < self.min_future_fraction <= 1:
            raise ValueError(f"HeuristicConfig.min_future_fraction must be in (0, 1], got {self.min_future_fraction}")
