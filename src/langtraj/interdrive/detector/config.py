"""Thresholds of the rule-based interaction detector (docs/interdrive.md, 'Interaction labels')."""

from __future__ import annotations

import math
from dataclasses import dataclass

from langtraj.scenario.types import AgentType

MOVERS = (AgentType.VEHICLE, AgentType.CYCLIST)
"""Agent types that have paths, leaders and lanes."""


@dataclass(frozen=True)
class DetectorConfig:
    """Thresholds of the rules (m, m/s, m/s^2, radians, steps of 0.1 s)."""

    leader_range: float = 60.0  # m: largest bumper gap to a leader along the path
    leader_search: float = 70.0  # m: centre distance within which leaders are looked for
    leader_lateral: float = 1.5  # m: a leader's centre is at most this far from the follower's path
    straight_range: float = 30.0  # m: a leader straight ahead in the follower's heading frame counts up to this gap
    leader_heading: float = math.radians(45.0)  # a leader heads along the path within this
    path_spacing: float = 2.0  # m between resampled path points
    path_extension: float = 100.0  # m a path is extended straight past its last step (and 20 m before its first)
    min_follow_steps: int = 10  # steps a following run must last (1 s)
    follow_merge_gap: int = 2  # leader flickers up to this many steps are joined
    stopped_speed: float = 0.3  # m/s: at or below this an agent stands
    held_speed: float = 2.0  # m/s: below this a vehicle is held back
    braking: float = -0.5  # m/s^2: decelerating harder than this is held back
    foe_horizon_s: float = 4.0  # s: a foe counts while at most this far (in time) from the conflict point
    conflict_radius: float = 1.5  # m: two paths this close form a conflict point
    conflict_heading: float = math.radians(20.0)  # paths must cross at more than this angle
    wait_extension: float = 15.0  # m a yielding vehicle's path is extended past its last step (no map lane)
    continue_on_map: bool = False  # continue a vehicle standing all window along its map lane branches (opt-in)
    continuation_length: float = 60.0  # m of map lanes a path is continued by past its last step
    merge_gap: int = 5  # yield runs up to this many steps apart are joined
    min_event_steps: int = 5  # yield runs shorter than this are dropped
    red_distance: float = 12.0  # m: a stop point this far ahead of a vehicle's front with a non-go light holds it
    red_lateral: float = 2.0  # m: a stop point this close to a vehicle's heading line is on its way (red-light runs)
    red_crossing_s: float = 4.0  # s after running a red light within which it must cross the other's path
    red_conflict_radius: float = 2.5  # m: a red-light runner this close to the other's heading line is on it
    red_foe_range: float = 15.0  # m: the other within this (or `foe_horizon_s` at its speed) of the crossing counts
    ped_lookahead: float = 12.0  # m ahead of a vehicle's front checked against crosswalks
    crosswalk_margin: float = 0.5  # m: a vehicle centre this close to a crosswalk is on it
    wait_to_cross_steps: int = 10  # a standing pedestrian must step onto the crosswalk within this many steps
    crosswalk_search: float = 5.0  # m: a pedestrian standing to the window's end waits at a crosswalk this near
    lane_match_distance: float = 2.0  # m: a lane centreline at most this far is the agent's lane
    lane_match_heading: float = math.radians(45.0)  # and heading along the agent within this
    lane_width_range: tuple[float, float] = (2.0, 5.0)  # m: offset of a parallel neighbour lane (no neighbour data)
    min_lane_steps: int = 3  # steps an agent must stay on a lane for the lane to count
    lane_change_half_span: int = 20  # steps a lane-change label reaches either side of the switch
    target_lane_range: float = 150.0  # m: a leader on the target lane of a lane change is looked for this far
    target_lane_lateral: float = 1.6  # m: a centre this close to a lane centreline is on that lane
    ring_length: float = 250.0  # m: a roundabout ring is at most this long
    ring_min_curvature: float = math.radians(0.5)  # rad/m: every ring lane turns the ring's way at least this much
    ring_min_roundness: float = 0.7  # a ring's least centroid distance is at least this share of its largest
    ring_short_lane: float = 2.0  # m: ring lanes shorter than this are exempt from `ring_min_curvature`
    static_displacement: float = 1.0  # m: an agent whose valid positions span at most this stands all window
    lane_change_min_speed: float = 2.0  # m/s: median speed within `lane_change_speed_steps` of a lane switch
    lane_change_speed_steps: int = 10  # steps either side of a switch over which its speed is taken
    lane_change_min_lateral: float = 1.5  # m: least sideways move across the target lane that confirms a switch
    lane_change_lateral_steps: int = 30  # steps either side of a switch between which the sideways move is taken
    lane_change_max_lateral: float = 8.0  # m: a larger sideways move is no change to a neighbour lane
    cut_in_range: float = 10.0  # m: a vehicle in the target lane this near behind a lane change is cut in on ...
    cut_in_headway_s: float = 2.0  # s: ... or within this time gap at its speed (the two-second rule)
    lane_runs_on: float = 5.0  # m: a target lane without successors must run on this far past the lane left
    overtake_lookback: int = 15  # steps before a switch at which the former leader is looked up
    high_speed: float = 20.0  # m/s: an overtake at or above this top speed is high-speed
    overtake_cut_in_lookback: int = 80  # steps before a cut-in's switch within which having been behind is an overtake
    tailgating_headway_s: float = 0.6  # s: following with a time headway below this at speed is tailgating
    tailgating_speed: float = 5.0  # m/s
    hard_braking: float = 3.0  # m/s^2: a lead slowing this hard on average over `hard_braking_steps` brakes hard
    hard_braking_steps: int = 5  # steps (0.5 s) over which hard braking is averaged
    hard_braking_speed: float = 3.0  # m/s: hard braking starts at least this fast
    braking_response_s: float = 2.0  # s after a lead's hard braking that its label covers (the follower's response)
    pull_out_speed: float = 3.0  # m/s: at most this fast, off another's line, a vehicle waits to pull out ...
    pull_out_lookback_s: float = 4.0  # s: ... within this before it comes onto that line
    pull_out_heading: float = math.radians(30.0)  # heading across the other's line by this much (or on no lane)
    pull_out_on_line: float = 1.5  # m: a vehicle this close to the other's heading line has pulled out onto it
    pull_out_other_speed: float = 3.0  # m/s: the vehicle pulled out in front of drives at least this fast
    slow_lead_ratio: float = 0.6  # a leader at most this share of the follower's earlier top speed is slow
    min_window_s: float = 1.0  # a label must overlap the current and future steps by this long
