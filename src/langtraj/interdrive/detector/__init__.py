"""A rule-based interaction detector from trajectories and map alone (no simulator events).

For real scenes (Waymo, nuScenes) and to pre-fill the labeling tool; docs/interdrive.md ('Interaction labels')
describes it and docs/benchmarks.md ('InterDrive labels') measures it. One `InteractionRule` per interaction type,
registered in `INTERACTION_RULES`; `detect_interactions` runs them all over one shared, lazily computed
`SceneGeometry`. Modules: `config` (thresholds), `arrays` (`SceneArrays`: the agents' arrays and who stands),
`parts` (`Pair` and the `ScenePart` base), `scene` (`SceneGeometry`, its parts built in dependency order), `paths`
(paths, leaders, following), `lanes` (lane matches, lane leaders, roundabouts), `lane_changes` (lane changes,
merges, overtakes), `yields` (held vehicles, conflict points), `crosswalks` (pedestrians), `red_lights` (red lights
run across another's path), `pull_outs` (pulling out in front of another), `rules` (the rules); each
part imports only the parts it reads, so no module imports one that imports it back. Lane primitives shared
with the heuristic labeler (`LaneChange`, neighbour lanes, the road-side test of parked cars) are in `roads`
(`roads.records.LaneChange`, `MapIndex`).
One ordered pair can be judged alone by the rules' own definitions: `yielding_runs`, `passing_runs`,
`following_runs`, `cut_in_runs`, `overtake_cut_in_runs`, `braking_lead_runs`, `tailgating_runs`, `red_light_runs`
and `pull_out_runs` give the runs of the pair's labels of that
type that `detect_interactions` keeps, computing only what the pair needs (the two agents' paths, held steps, red
lights and standing, and the leaders of the one that waits, per agent and only at the steps that decide); `pair_rows`
names the agents they read, so a scene may be cut to those. The rules over all pairs run the same per-pair
definitions (`YieldGeometry.pair_yields`, `CrosswalkGeometry.pedestrian_yield_runs` and `pedestrian_wait_runs`,
`PathGeometry.following`) over every pair.
Candidate selection in simulation judges pair prompts with them (`sim.adherence`).
The rules mirror how `ground_truth.py` defines each type from SUMO's events, so the two can be compared with
`evaluation.match_interactions`:

- leader (shared): agent L is F's leader at step t when L's centre lies on F's path (F's own trajectory over
  the window, extended straight at both ends) within `leader_lateral` of it, heading along it, ahead of F by a
  bumper gap of at most `leader_range` (60 m, the range of SUMO's `follow` events), and no other vehicle or
  cyclist is nearer on that path.
- lane leader (shared): the leader of agent A on map lane X at step t is the nearest vehicle or cyclist ahead of A
  (within `target_lane_range`) whose centre lies within `target_lane_lateral` of X or of X's successors along A's
  way (junction lanes included; at a split only the branches A's later trajectory runs along), heading along them.
- standing agents: an agent whose valid positions over the whole window (history included) span at most
  `static_displacement` is static; a static one on no map lane (road side, parking lot) is parked.
- following: runs of at least `min_follow_steps` with the same leader (flickers up to `follow_merge_gap` joined).
  A parked follower follows no one, and a static follower no parked leader (cars parked in a row); a static
  follower on a lane behind a leader on a lane is a queue (at a red light or a junction) and is kept. Subtypes
  read only steps where both are valid.
- lane change: the agent's map lane (nearest non-junction lane centreline within `lane_match_distance`, heading
  within `lane_match_heading`) switches to a left/right neighbour lane (or, without neighbour data, to a parallel
  lane `lane_width_range` aside; see `MapIndex.neighbor_side`), confirmed as a manoeuvre (not a flicker of the
  nearest lane): the agent is not static, drives at a median `lane_change_min_speed` around the switch, and its
  signed offset from both the lane left and the lane entered changes by `lane_change_min_lateral` to
  `lane_change_max_lateral` within `lane_change_lateral_steps` of it; switches of one agent closer than
  `lane_change_half_span` are one manoeuvre. The other is the lane leader on the target lane right after the switch,
  or -1. Where the map has no lanes, `changing_lanes` agent labels stand in (the other is then the path leader). An
  overtaking lane change names the overtaken agent. A cut-in: a lane change (or merge) with a vehicle following in
  the target lane right after the switch, its front behind the changer's rear by at most `cut_in_range` or
  `cut_in_headway_s` at its speed (one still beside the changer is side-swiped, not cut in on).
- merging: a lane change out of a lane that ends while the lane entered goes on: the lane left has no successors,
  and the target lane has some or runs on `lane_runs_on` past the lane left's end (a map crop cuts both alike);
  a map without lane connectivity (nuScenes) shows no lane ending, so it has no merges.
  On-ramp subtypes when no lane before the lane left lies beside (or is) a lane before the target lane.
  Pulling out (a merging subtype): see `pull_outs` (A, nearly standing off B's heading line and across it or on no
  lane, comes onto that line just ahead of B).
- red-light running (a passing subtype): see `red_lights` (A passes a red stop point, then crosses B's heading line
  just ahead of B, or B yields to A).
- overtaking: a lane change of A whose former leader B (the lane leader on the lane left right before the switch)
  was slower, after which A gets ahead of B along B's heading within the window. Overtaking and cutting in: a
  cut-in by A in front of B (see lane changes) where A's rear was behind B's front (A behind or beside B), along B's
  heading, at a step within `overtake_cut_in_lookback` before the switch; it runs from that step to the change's end.
- yielding: (vehicles) the paths of A and B come within `conflict_radius` at a heading difference above
  `conflict_heading` (the conflict point); B reaches it first, and A is held (slower than `held_speed` or
  braking harder than `braking`, not in front of a red light, and not queued behind its own leader that is
  still before the conflict point) before it while B, not held itself, is at most `foe_horizon_s` from it, or
  is inside it, for `min_event_steps` (runs up to `merge_gap` apart joined); A's path is its trajectory extended
  straight by `wait_extension`, or, for an A standing all window (queued far back: its way on is unknown), its
  map lane and every chain of successor lanes when `continue_on_map` (off by default: on real scenes cars standing
  on lanes all window triple the yields; not over a signal-controlled lane, where the light decides, see `red`);
  a parked A yields to no one and
  no one yields to a B static all window. (pedestrians) A held vehicle whose
  look-ahead `ped_lookahead` m ahead of its front runs over a map crosswalk on which a pedestrian walks yields to
  the nearest such pedestrian. (pedestrian to vehicle) a pedestrian standing next to a crosswalk that it then
  steps onto (or, standing to the window's end, the crosswalk within `crosswalk_search`) yields to each vehicle
  that is on that crosswalk while it stands.
- passing: the reverse of every yield: B -> A at junctions (at roundabout when the map holds a round ring of
  curving lanes, see `LaneGeometry.has_roundabout`; `vru_crossing` for a cyclist B), pedestrian -> vehicle
  `vru_crossing`, vehicle -> waiting pedestrian `pedestrian`; and a lead braking hard in front of its follower,
  L -> F `braking_lead` (its speed, at least `hard_braking_speed`, drops by `hard_braking` on average over
  `hard_braking_steps` while F follows it; the label runs `braking_response_s` past the braking).

Only trajectories and the map are read (no simulator ids, events or window kind), so the rules run on real
scenes too. Single-agent labels are optional inputs: `changing_lanes` spans are used when the map has no lanes.
Labels are kept when they overlap [current_index, num_steps) by `min_window_s` (the ground truth's own window
filter) and are sorted as the ground truth's.
"""

from langtraj.interdrive.detector.config import DetectorConfig
from langtraj.interdrive.detector.rules import (
    INTERACTION_RULES,
    InteractionRule,
    braking_lead_runs,
    cut_in_runs,
    detect_interactions,
    following_runs,
    overtake_cut_in_runs,
    pair_rows,
    passing_runs,
    pull_out_runs,
    red_light_runs,
    tailgating_runs,
    yielding_runs,
)
from langtraj.interdrive.detector.scene import SceneGeometry

__all__ = [
    "INTERACTION_RULES",
    "DetectorConfig",
    "InteractionRule",
    "SceneGeometry",
    "braking_lead_runs",
    "cut_in_runs",
    "detect_interactions",
    "following_runs",
    "overtake_cut_in_runs",
    "pair_rows",
    "passing_runs",
    "pull_out_runs",
    "red_light_runs",
    "tailgating_runs",
    "yielding_runs",
]
