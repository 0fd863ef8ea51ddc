"""Heuristic single-agent labels (InterDrive 'Heuristic Annotation Process') over a scene's future window;
docs/interdrive.md describes them and docs/benchmarks.md ('InterDrive labels') measures them.

Every agent valid at the current step and over at least `HeuristicConfig.min_future_fraction` of the future
steps [current_index, num_steps) gets the labels whose rule holds, each with the window steps [start, end)
where it holds, so prompts can order them. Speed and acceleration come from positions (gaps filled
linearly, then smoothed), not from the velocity fields. Each label (or small family) is one `LabelRule`
registered in `LABEL_RULES`; `label_agents` runs them all. Where the map lacks what a rule needs (lanes,
connectivity, neighbour lists, road edges, crosswalks) the rule returns `Undecided` naming it. Lane primitives
shared with the interaction detector (`LaneChange`, neighbour lanes, the road-side test of parked vehicles) are in
`roads` (`roads.records.LaneChange`, `MapIndex`).

Modules: `config` (`HeuristicConfig`, the thresholds), `kinematics` (speed, acceleration, course from positions),
`runs` (per-step class sequences), `context` (`LabelContext`: what the rules share for one scene, lane matches,
parked vehicles, lane changes), `pull_over` (where a pull-over starts), `rules` (`LabelRule`s and `LABEL_RULES`),
`labeler` (`label_agents`, the entry point).
"""

from langtraj.interdrive.heuristics.config import HeuristicConfig
from langtraj.interdrive.heuristics.kinematics import Kinematics
from langtraj.interdrive.heuristics.labeler import label_agents
from langtraj.interdrive.heuristics.rules import LABEL_RULES, LabelRule
from langtraj.interdrive.heuristics.runs import absorb_short_runs

__all__ = [
    "LABEL_RULES",
    "HeuristicConfig",
    "Kinematics",
    "LabelRule",
    "absorb_short_runs",
    "label_agents",
]
