"""Behaviours staged at their trigger (docs/simulation.md, 'Timing in words'): a read behaviour whose prompt says when
it starts ("after 3 s", "when @1 is within 20 m of @7", "then") waits, driven as if unprompted, until its trigger
(`interdrive.triggers`) holds at a step of that rollout (checked at every step, `sim.scripted.act`); then its target is
derived from the agents' live state at that step, where they are and how fast they go, not where they were at the
start, and steered from it, timed from that step. Where the scene gives no target when the trigger holds, it is tried
again at the next step, and the report says why.

A behaviour that starts at once is anchored at the start as before; its completion (`target_done`) starts a sequence's
next clause.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from langtraj.frames import Origin
from langtraj.guidance.steering import Steering
from langtraj.interdrive.behaviours.base import HOLD_WEIGHT, REACH_WEIGHT, kind, route
from langtraj.interdrive.behaviours.base import lead as lead_steer
from langtraj.interdrive.behaviours.verdict import Start
from langtraj.interdrive.reader import PromptReading
from langtraj.interdrive.targets import BehaviourTarget, TargetUnavailable, derive_target
from langtraj.interdrive.targets.context import TargetContext, lead_of
from langtraj.interdrive.triggers import STOPPED_MPS, AfterDone, AtTime, Now, Trigger, WhenReady, Within, pose_at
from langtraj.polylines import project_on_polyline
from langtraj.roads import MapIndex
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS, Scenario
from langtraj.sim.adherence import Ask

DONE_FALLBACK_S = 3.0
"""When a behaviour whose target times nothing and has no goal on a path counts as done (s after it started)."""


@dataclass(frozen=True)
class Staged:
    """A read behaviour that starts at its `trigger`: the reading, the slot of its agent, and its index among the
    simulation's asks with the ask (None without the selection lever)."""

    reading: PromptReading
    trigger: Trigger
    slot: int
    ask: int | None = None
    ask_of: Ask | None = None
    """What selection judges of it once started."""


@dataclass
class Anchor:
    """Where a staged behaviour started in one rollout: the step, its target then (world frame) and its steering
    (scene frame)."""

    step: int
    target: BehaviourTarget
    steering: Steering


@dataclass
class Waiting:
    """A staged behaviour not started yet in one rollout: what its trigger read at the last replan, and why its
    target was not derived where the trigger held (empty when it never held)."""

    measured: str = ""
    unavailable: str = ""


KEEP_SLACK_M = 2.0
"""How far a staged agent keeping its place may drift from its start's offset to the other agent, either way (m)."""


def keeping(
    scenario: Scenario,
    reading: PromptReading,
    index: MapIndex,
    origin: Origin,
    slots: dict[int, int],
    routes: Mapping[int, np.ndarray] | None = None,
) -> Steering | None:
    """Until a behaviour timed by the clock or by another's behaviour starts, its agent keeps the place it has at the
    start relative to the other agent (within `KEEP_SLACK_M`, along its own lane), from where the behaviour could
    be staged then (`suggest` found it so), instead of drifting wherever the model takes it; where the behaviour's
    kind keeps a place of its own (`BehaviourKind.placed`: a cutter at its lead beside the other, executed by its
    script), that one, read with the external agents' `routes` (`TargetContext.routes`). A behaviour started when
    the other comes within a gap of its agent ("when @ego is within 20 m of @4") keeps the place its kind has for
    that gap (a braking lead easing off), where it has one. None for a behaviour of one agent, toward an agent the
    simulation does not drive, or started otherwise."""
    within = _within_m(reading)
    timed = isinstance(reading.trigger, (AtTime, AfterDone))
    if not (timed or within is not None) or reading.other not in slots:
        return None
    assert reading.agent is not None and reading.behaviour is not None
    placed = _placed(scenario, reading, index, routes or {}, within)
    if placed is not None:
        return Steering.of(placed, origin, slots)
    if not timed:
        return None
    ctx = TargetContext(scenario, index)
    try:
        agent, other = ctx.agent(reading.agent, reading.behaviour), ctx.agent(int(reading.other), reading.behaviour)
    except TargetUnavailable:
        return None
    lead = lead_of(agent, other)
    target = BehaviourTarget(
        agent.track_id,
        reading.behaviour,
        ctx.ahead(agent),
        f"keeps {lead:.0f} m ahead of @{other.track_id} until it starts",
        other_id=other.track_id,
        current_speed=agent.here.speed,
        other_speed=other.here.speed,
    )
    steers = (
        lead_steer(lead - KEEP_SLACK_M, "reach", 1, FUTURE_STEPS, REACH_WEIGHT)
        + lead_steer(lead + KEEP_SLACK_M, "hold", 1, FUTURE_STEPS, HOLD_WEIGHT)
        + route()
    )
    return Steering.of(target, origin, slots, tuple(steers))


def _within_m(reading: PromptReading) -> float | None:
    """The bumper gap (m) at which the reading's trigger starts it, where that trigger is the gap between its agent
    and the other ("when @ego is within 20 m of @4, @4 brakes hard in front of @ego"); else None."""
    trigger = reading.trigger
    if not isinstance(trigger, Within) or trigger.metres is None:
        return None
    return float(trigger.metres) if {trigger.subject, trigger.other} == {reading.agent, reading.other} else None


def _placed(
    scenario: Scenario,
    reading: PromptReading,
    index: MapIndex,
    routes: Mapping[int, np.ndarray],
    within_m: float | None = None,
) -> BehaviourTarget | None:
    """The place the reading's kind keeps its agent in until it starts (`BehaviourKind.placed`, with the trigger's
    gap `within_m`), from its target at the start; None where the kind keeps none or the start gives no target."""
    assert reading.agent is not None and reading.behaviour is not None
    try:
        target = derive_target(scenario, reading.agent, reading.behaviour, index, other_id=reading.other,
                               gap=reading.metres, deceleration=reading.deceleration, routes=routes)  # fmt: skip
    except TargetUnavailable:
        return None
    return kind(reading.behaviour).placed(target, within_m)


def target_done(target: BehaviourTarget, since: int, scene: Scenario) -> bool:
    """Whether the behaviour toward `target`, started at step `since`, is done at the scene's current step: its
    timed goal reached (`settled_s`), else its agent at its goal along its path (standing there for a stop), else
    `DONE_FALLBACK_S` after it started."""
    step = int(scene.current_index)
    elapsed = (step - since) * STEP_SECONDS
    if target.settled_s is not None:
        return elapsed >= target.settled_s
    if target.station_of_goal is None or len(target.path) < 2:
        return elapsed >= DONE_FALLBACK_S
    pose = pose_at(scene, target.track_id)
    if pose is None:
        return False
    xy, _, speed, _ = pose
    station = float(project_on_polyline(xy[None], target.path).station[0])
    if target.stop:
        return speed <= STOPPED_MPS and station >= target.station_of_goal - 5.0
    return station >= target.station_of_goal


@dataclass
class Stagings:
    """The staged behaviours of one simulation and, per rollout, where each started (`anchors`) or what it waits for
    (`waiting`); `started` are the behaviours anchored at the start (their targets, for a sequence's `done`)."""

    staged: tuple[Staged, ...]
    origin: Origin
    slots: dict[int, int]
    index: MapIndex
    start: int
    started: tuple[BehaviourTarget, ...] = ()
    keep: dict[int, Steering] = field(default_factory=dict)
    """Staged behaviour -> the steering that keeps its agent's place until it starts (`keeping`), where one does."""
    routes: Mapping[int, np.ndarray] = field(default_factory=dict)
    """The routes the external agents drive (`SimWorld.routes`: an ego's mission), which targets toward them read."""
    anchors: dict[int, dict[int, Anchor]] = field(default_factory=dict)
    waiting: dict[int, dict[int, Waiting]] = field(default_factory=dict)
    done: dict[int, dict[int, float]] = field(default_factory=dict)
    """Per rollout: track id -> when its prompted behaviour was done (s since the start)."""
    checked: dict[int, int] = field(default_factory=dict)
    """Per rollout: the last step it was checked at (a replan's step is asked twice: by the plan and by its step)."""

    def __bool__(self) -> bool:
        return bool(self.staged)

    def update(self, scenario_at: Callable[[int, int], Scenario], step: int, rollouts: list[int]) -> None:
        """Check every staged behaviour not started in `rollouts` at `step` (`scenario_at(rollout, step)`: the
        rollout's scene as it is then) and start those whose trigger holds and whose target the scene gives."""
        for r in rollouts:
            if len(self.anchors.get(r, {})) == len(self.staged) or self.checked.get(r) == step:
                continue  # all started (nothing waits, nothing to read), or checked at this step already
            self.checked[r] = step
            scene = scenario_at(r, step)
            elapsed = (step - self.start) * STEP_SECONDS
            self._mark_done(r, scene, elapsed)
            now = Now(scene, elapsed, self.done.get(r, {}))
            anchors = self.anchors.setdefault(r, {})
            for k, staged in enumerate(self.staged):
                if k in anchors:
                    continue
                wait = self.waiting.setdefault(r, {}).setdefault(k, Waiting())
                wait.measured = staged.trigger.measured(now)
                if not staged.trigger.holds(now):
                    continue
                reading = staged.reading
                assert reading.behaviour is not None and reading.agent is not None
                try:
                    target = derive_target(
                        scene,
                        reading.agent,
                        reading.behaviour,
                        self.index,
                        other_id=reading.other,
                        gap=reading.metres,
                        deceleration=reading.deceleration,
                        routes=self.routes,
                    )
                except TargetUnavailable as exc:
                    wait.unavailable = self._not_yet(staged, elapsed, str(exc.detail))
                    continue
                behaviour = kind(reading.behaviour)
                if not isinstance(staged.trigger, WhenReady):  # the prompt says when: at once from then
                    target = behaviour.at_trigger(target)
                why = behaviour.ready(target)
                if why is not None:
                    wait.unavailable = self._not_yet(staged, elapsed, why)
                    continue
                anchors[k] = Anchor(step, target, Steering.of(target, self.origin, self.slots))
                self.waiting[r].pop(k, None)

    @staticmethod
    def _not_yet(staged: Staged, elapsed: float, why: str) -> str:
        """Why a staged behaviour whose trigger held did not start at the step `elapsed` s after the start."""
        if isinstance(staged.trigger, WhenReady):
            return f"not stageable at {elapsed:.1f} s: {why}"
        return f"its trigger held at {elapsed:.1f} s but {why}"

    def _mark_done(self, rollout: int, scene: Scenario, elapsed: float) -> None:
        done = self.done.setdefault(rollout, {})
        started = [(t, self.start) for t in self.started]
        started += [(a.target, a.step) for a in self.anchors.get(rollout, {}).values()]
        for target, since in started:
            if target.track_id not in done and target_done(target, since, scene):
                done[target.track_id] = elapsed

    def started_in(self, rollout: int) -> list[tuple[Staged, Anchor]]:
        """The staged behaviours started in `rollout`, with where."""
        anchors = self.anchors.get(rollout, {})
        return [(self.staged[k], anchors[k]) for k in sorted(anchors)]

    def is_waiting(self, rollout: int, k: int) -> bool:
        return k not in self.anchors.get(rollout, {})

    def keeping_in(self, rollout: int) -> list[Steering]:
        """The steerings keeping the places of the staged behaviours not started in `rollout` (`keeping`)."""
        return [steering for k, steering in sorted(self.keep.items()) if self.is_waiting(rollout, k)]

    def waiting_slots(self, rollout: int) -> set[int]:
        """Slots of the agents whose staged behaviour has not started in `rollout` (driven as if unprompted)."""
        return {s.slot for k, s in enumerate(self.staged) if self.is_waiting(rollout, k)}

    def report(self, num_rollouts: int) -> list[dict[str, Any]]:
        """Per staged behaviour: its trigger and, per rollout, when it started (s since the start) and its target, or
        what the trigger read last and why no target (results.json, the suites' verdicts)."""
        out = []
        for k, staged in enumerate(self.staged):
            per: list[dict[str, Any]] = []
            for r in range(num_rollouts):
                anchor = self.anchors.get(r, {}).get(k)
                if anchor is not None:
                    at = (anchor.step - self.start) * STEP_SECONDS
                    per.append({"started_s": round(at, 2), "step": anchor.step, "target": anchor.target.reason})
                else:
                    wait = self.waiting.get(r, {}).get(k, Waiting())
                    per.append({"started_s": None, "measured": wait.measured, "unavailable": wait.unavailable})
            out.append({"agent": staged.reading.agent, "trigger": staged.trigger.describe(), "rollouts": per})
        return out


def starts_of(report: dict[str, Any], rollout: int = 0) -> dict[int, Start]:
    """Track id -> when its staged behaviour started in `rollout` (`Start`), read from a simulation's report (its
    `prompt.staged`, `Stagings.report`); empty where nothing was staged."""
    out: dict[int, Start] = {}
    for entry in (report.get("prompt") or {}).get("staged", []):
        per = entry["rollouts"][rollout]
        if per["started_s"] is not None:
            out[int(entry["agent"])] = Start(int(per["step"]), float(per["started_s"]))
            continue
        why = per["unavailable"] or f"its start ({entry['trigger']}) never held" + (
            f": at the end {per['measured']}" if per["measured"] else ""
        )
        out[int(entry["agent"])] = Start(None, None, why)
    return out
