"""Scenes built in memory for the environment's tests: a straight two-lane road with an ego and the car that
follows it (no files needed)."""

from __future__ import annotations

from scenario_builders import two_lane_road

from langtraj.scenario import Scenario

EGO_ID, FOLLOWER_ID = 1, 2


def follower_scene(gap_m: float = 12.0, speed: float = 10.0, others: int = 2, steps: int = 91) -> Scenario:
    """A 500 m straight road, two lanes eastbound; the ego (id 1, the self-driving car) at x = 0 in the right lane
    and a follower (id 2) `gap_m` behind it (bumper to bumper), both at `speed`, with `others` cars in the left lane.
    The log has everyone keep their speed for `steps` steps (9.1 s: one window)."""
    starts = [(0.0, 0.0), (-(gap_m + 4.5), 0.0)] + [(-30.0 + 25.0 * k, 3.5) for k in range(others)]
    return two_lane_road([(x, y, speed) for x, y in starts], scenario_id="follower", steps=steps)
