"""The cautious planner: the IDM lane follower tuned to brake for any agent ahead in its path, early and by a wide
margin, and to drive below the limit; the careful end of the three planners a scenario is checked against (with
`idm` and the careless `constant_velocity`: docs/testing.md, 'Planners to calibrate against')."""

from __future__ import annotations

from langtraj.planners.base import PLANNERS
from langtraj.planners.idm import IDMConfig, IDMPlanner

CAUTIOUS = IDMConfig(
    speed_limit_factor=0.8,
    time_headway=2.5,
    min_gap=4.0,
    max_accel=1.0,
    corridor_margin=1.0,
    cut_in_horizon=3.0,
    crossing_traffic=True,
)
"""Its settings: 80 % of the limit, 2.5 s of headway and 4 m standing gap (the IDM's 1.5 s and 2 m), a 1 m margin
on the corridor (an agent straddling the lane line is in its path) and a 3-s look at agents heading its way or
crossing it (a cut-in seen coming three times as early, a car crossing against its light seen coming at all), gentle
to speed up."""


@PLANNERS.register
class CautiousPlanner(IDMPlanner):
    """Brakes for any agent ahead in its path (see the module docstring): a planner that should pass every scenario
    that can be passed."""

    name = "cautious"

    def __init__(self, config: IDMConfig | None = None):
        super().__init__(config or CAUTIOUS)
