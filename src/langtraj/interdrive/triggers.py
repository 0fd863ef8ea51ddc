"""When a prompted behaviour starts: a trigger read from the prompt's timing words ("after 3 s", "when @1 is within
20 m of @7", "once @4 has stopped", "@4 turns left, then @7 ...") and checked on the scene as it is now. A simulation
stages the behaviour from the first replan at which its trigger holds, deriving its target from the agents' live
state then (`sim.staging`); the judge reads the manoeuvre after that step. The same `holds` serves both, so what
starts a behaviour and what the report says started it are one rule (docs/interdrive.md, 'Timing in words').

A trigger reads only the current step and the past of the scene it is given, never a logged future.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import StateField

STOPPED_MPS = 0.5
"""At or below this speed an agent has stopped (m/s), as the labelers' stop."""


@dataclass(frozen=True)
class Now:
    """What a trigger is checked against: the scene at its current step (`scene.current_index`), the seconds since
    the simulation's start, and the agents whose own prompted behaviour is done, with when (s since the start; for a
    sequence)."""

    scene: Scenario
    elapsed_s: float
    done: Mapping[int, float] = field(default_factory=dict)

    def pose(self, track_id: int) -> tuple[np.ndarray, float, float, float] | None:
        """(xy [2], heading, speed, length) of `track_id` at the current step, or None where it is absent there."""
        return pose_at(self.scene, track_id)


def pose_at(scene: Scenario, track_id: int) -> tuple[np.ndarray, float, float, float] | None:
    """(xy [2], heading, speed, length) of `track_id` at the scene's current step, or None where it is absent or not
    valid there."""
    agents, t = scene.agents, int(scene.current_index)
    try:
        row = agents.index_of(track_id)
    except KeyError:
        return None
    if not agents.valid[row, t]:
        return None
    xy = agents.xy[row, t].astype(float)
    length = float(agents.states[row, t, StateField.LENGTH])
    return xy, float(agents.heading[row, t]), float(agents.speed[row, t]), length


class Trigger(ABC):
    """A condition on the scene as it is now; `agents` are the tracks it names (each must be in the scene)."""

    @abstractmethod
    def holds(self, now: Now) -> bool:
        """Whether the behaviour may start now."""

    @abstractmethod
    def describe(self) -> str:
        """A phrase for `read as` and the reports: "from 3 s", "when @1 is within 20 m of @7"."""

    @property
    def agents(self) -> tuple[int, ...]:
        return ()

    def measured(self, now: Now) -> str:
        """What the trigger reads now, for a report of why it never held ("@1 35 m from @7"); empty when nothing."""
        return ""


@dataclass(frozen=True)
class AtTime(Trigger):
    """From `seconds` after the start ("after 3 s", "at 4 s", "3 seconds from now")."""

    seconds: float

    def holds(self, now: Now) -> bool:
        return now.elapsed_s >= self.seconds - 0.5 * STEP_SECONDS

    def describe(self) -> str:
        return f"from {self.seconds:g} s"


@dataclass(frozen=True)
class Within(Trigger):
    """When `subject` is within `metres` of `other` (bumper to bumper) or within `seconds` at its own speed (a time
    headway): "when @1 is within 20 m of @7", "once @1 is 2 s behind @7"."""

    subject: int
    other: int
    metres: float | None = None
    seconds: float | None = None

    def gap(self, now: Now) -> tuple[float, float] | None:
        """(bumper-to-bumper distance m, the subject's speed m/s) now, or None when either is absent."""
        a, b = now.pose(self.subject), now.pose(self.other)
        if a is None or b is None:
            return None
        centres = float(np.hypot(*(a[0] - b[0])))
        return max(centres - 0.5 * (a[3] + b[3]), 0.0), a[2]

    def holds(self, now: Now) -> bool:
        found = self.gap(now)
        if found is None:
            return False
        gap, speed = found
        if self.metres is not None:
            return gap <= self.metres
        assert self.seconds is not None
        return gap <= self.seconds * speed

    def describe(self) -> str:
        within = f"{self.metres:g} m" if self.metres is not None else f"{self.seconds:g} s"
        return f"when @{self.subject} is within {within} of @{self.other}"

    @property
    def agents(self) -> tuple[int, ...]:
        return (self.subject, self.other)

    def measured(self, now: Now) -> str:
        found = self.gap(now)
        if found is None:
            return ""
        gap, speed = found
        if self.metres is not None:
            return f"@{self.subject} {gap:.0f} m from @{self.other}"
        return f"@{self.subject} {gap / max(speed, 0.1):.1f} s from @{self.other}"


@dataclass(frozen=True)
class Stopped(Trigger):
    """Once `subject` has stopped ("once @4 has stopped", "when @4 comes to a stop")."""

    subject: int

    def holds(self, now: Now) -> bool:
        pose = now.pose(self.subject)
        return pose is not None and pose[2] <= STOPPED_MPS

    def describe(self) -> str:
        return f"once @{self.subject} has stopped"

    @property
    def agents(self) -> tuple[int, ...]:
        return (self.subject,)

    def measured(self, now: Now) -> str:
        pose = now.pose(self.subject)
        return "" if pose is None else f"@{self.subject} at {pose[2]:.1f} m/s"


@dataclass(frozen=True)
class Passed(Trigger):
    """Once `subject` is past `other`: its centre ahead of the other's front along the other's heading ("once @4
    has passed @7", "after @4 goes past")."""

    subject: int
    other: int

    def ahead(self, now: Now) -> float | None:
        """How far the subject's centre is ahead of the other's front along the other's heading (m), or None."""
        a, b = now.pose(self.subject), now.pose(self.other)
        if a is None or b is None:
            return None
        along = float(np.dot(a[0] - b[0], [np.cos(b[1]), np.sin(b[1])]))
        return along - 0.5 * b[3]

    def holds(self, now: Now) -> bool:
        ahead = self.ahead(now)
        return ahead is not None and ahead > 0.0

    def describe(self) -> str:
        return f"once @{self.subject} has passed @{self.other}"

    @property
    def agents(self) -> tuple[int, ...]:
        return (self.subject, self.other)

    def measured(self, now: Now) -> str:
        ahead = self.ahead(now)
        return "" if ahead is None else f"@{self.subject} {-ahead:.0f} m short of passing @{self.other}"


@dataclass(frozen=True)
class AfterDone(Trigger):
    """After `subject`'s own prompted behaviour is done ("@4 turns left, then @7 ..."), plus `delay_s` ("then, 2 s
    later, ..."): a sequence."""

    subject: int
    delay_s: float = 0.0

    def holds(self, now: Now) -> bool:
        done = now.done.get(self.subject)
        return done is not None and now.elapsed_s >= done + self.delay_s - 0.5 * STEP_SECONDS

    def describe(self) -> str:
        later = f" and {self.delay_s:g} s" if self.delay_s > 0 else ""
        return f"after @{self.subject}'s behaviour{later}"

    @property
    def agents(self) -> tuple[int, ...]:
        return (self.subject,)


@dataclass(frozen=True)
class WhenReady(Trigger):
    """As soon as the scene allows the behaviour: its target derived from the agents as they are now, and ready
    (`BehaviourKind.ready`). The start of a behaviour put in an external agent's path (an ego under a planner) whose
    prompt says no time: staged on that agent's live state, wherever the planner has driven it."""

    def holds(self, now: Now) -> bool:
        return True

    def describe(self) -> str:
        return "as soon as the scene allows it"
