"""Guidance toward a prompted agent's target: the terms that steer it to do what its prompt asks.

The extended CTG++-style library: where `guidance.library` maps a label to generic costs around the agent's
current pose, this turns the steering a behaviour declares for its target (`BehaviourKind.steer`: `Steer` records
of route, station, speed, lead and spacing, in `interdrive.behaviours`) into costs. Targets are timed in simulated
steps from the start (1 ... 80); a replan that has already executed `elapsed` steps gets the terms for what is left,
in its own plan steps.

Common range, as in the library: a clear violation (1 m off the route, 5 m short of a goal, 2 m/s of speed
error) costs about 1.

See docs/simulation.md ('Prompts that steer').
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

from langtraj.frames import Origin, points_to_frame
from langtraj.guidance.base import GuidanceTerm
from langtraj.guidance.costs import NoCollisionCost, TargetSpeedCost
from langtraj.guidance.library import AVOID_WEIGHT, SPEED_WEIGHT
from langtraj.guidance.route import LeadCost, RouteCost, RoutePath, StationCost
from langtraj.interdrive.behaviours import Steer, kind
from langtraj.interdrive.targets import BehaviourTarget
from langtraj.scenario.model import FUTURE_STEPS

CLEAR_WEIGHT = AVOID_WEIGHT  # per unit of summed disk overlap with the other agents (as the library keeps clear)
CLEAR_BUFFER = 0.5  # m kept beyond touching


class ClearOfOthersCost(NoCollisionCost):
    """`NoCollisionCost` of one agent against every other with the "sum" reduction (not divided by the square of
    the agents involved): the agent's total disk overlap, whatever the scene's size."""

    name = "clear_of_others"

    def __init__(self, slot: int, *, buffer: float = 0.0):
        super().__init__(slot, buffer=buffer, reduction="sum")


@dataclass(frozen=True)
class Steering:
    """A target in the scene frame with the model slots of its agent (and of the other agent, if simulated)."""

    target: BehaviourTarget
    slot: int
    other_slot: int | None = None
    declared: tuple[Steer, ...] | None = None
    """The steering to apply in place of the behaviour's own (`BehaviourKind.steer`): a staged behaviour keeping
    its place until it starts (`sim.staging`)."""

    @classmethod
    def of(
        cls,
        target: BehaviourTarget,
        origin: Origin,
        slots: dict[int, int],
        declared: tuple[Steer, ...] | None = None,
    ) -> Steering:
        """`target` (world frame) moved into the scene frame of `origin`; `slots` maps track ids to slots."""
        moved = replace(
            target,
            path=points_to_frame(target.path, origin) if len(target.path) else target.path,
            conflict=None if target.conflict is None else points_to_frame(target.conflict, origin),
            own_lane=None if target.own_lane is None else points_to_frame(target.own_lane, origin),
            new_lane=None if target.new_lane is None else points_to_frame(target.new_lane, origin),
        )
        other = None if target.other_id is None else slots.get(target.other_id)
        return cls(moved, slots[target.track_id], other, declared)

    @cached_property
    def route(self) -> RoutePath:
        """The target's path as the route costs take it, built once for every replan's terms."""
        return RoutePath(self.target.path)

    def terms(self, elapsed: int, horizon: int) -> list[GuidanceTerm]:
        """The terms for a plan of `horizon` steps made after `elapsed` simulated steps: toward the target, and
        clear of every other agent (so that a step toward the target does not drive into someone)."""
        declared = self.declared
        if declared is None:
            declared = tuple(kind(self.target.behaviour).steer(self.target, self.other_slot is not None))
        clock = _Clock(elapsed, horizon)
        terms = [term for steer in declared for term in self._term(steer, clock)]
        if not terms:
            return terms
        return [*terms, GuidanceTerm(ClearOfOthersCost(self.slot, buffer=CLEAR_BUFFER), CLEAR_WEIGHT)]

    def _term(self, steer: Steer, clock: _Clock) -> list[GuidanceTerm]:
        """The cost of one declared term over the plan steps it covers (none where no step is left, the target has
        no path for a route, station or lead, or the other agent is not driven for a lead or spacing)."""
        if steer.kind == "avoid":
            if self.other_slot is None:
                return []
            return [GuidanceTerm(NoCollisionCost(self.slot, others=self.other_slot, buffer=steer.value), AVOID_WEIGHT)]
        span = clock.window(steer.first, steer.last)
        if span is None:
            return []
        start, end = span
        if steer.kind == "speed":
            weight = SPEED_WEIGHT if steer.weight is None else steer.weight
            return [GuidanceTerm(TargetSpeedCost(self.slot, steer.value, start=start, end=end), weight)]
        if len(self.target.path) < 2:
            return []
        weight = float(steer.weight if steer.weight is not None else 1.0)
        if steer.kind == "route":
            return [GuidanceTerm(RouteCost(self.slot, self.route, start=start, end=end), weight)]
        if steer.kind == "station":
            cost = StationCost(self.slot, self.route, steer.value, mode=steer.mode, start=start, end=end)
            return [GuidanceTerm(cost, weight)]
        if self.other_slot is None:
            return []
        lead = LeadCost(self.slot, self.other_slot, self.route, steer.value, mode=steer.mode, start=start, end=end)
        return [GuidanceTerm(lead, weight)]


@dataclass(frozen=True)
class _Clock:
    """Simulated steps (1 = the first after the start) to plan steps of a replan after `elapsed` steps."""

    elapsed: int
    horizon: int

    def window(self, first: int = 1, last: int = FUTURE_STEPS) -> tuple[int, int] | None:
        """Plan steps [start, end) covering simulated steps first ... last; None when none is left."""
        start = max(first - self.elapsed - 1, 0)
        end = min(last - self.elapsed, self.horizon)
        return (start, end) if end > start else None
