"""The behaviour interface: everything LangTraj knows of one behaviour a prompt can ask, declared in one place.

A `BehaviourKind` is one class in its own module of this package, registered in `KINDS` under its name: its words for
the prompt reader, its parameters (name, unit, default, accepted range), where a scene lets an agent stage it and the
target it steers to (`target`: the place, the gap, the stop point, or why there is none), its steering terms
(`steer`, declared as `Steer` records that `guidance.steering` turns into costs), and its judges (the labelers'
facts or the detector's per-pair rule, and by numbers: `judge`). The reader, feasibility, targets, steering,
candidate adherence, the suites and the studio ask the registry. See docs/design.md, 'Behaviours'.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Literal

from langtraj.errors import InputError
from langtraj.interdrive.behaviour import KINDS, BehaviourSpec, names
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS

if TYPE_CHECKING:
    from langtraj.interdrive.behaviours.scripts import Script
    from langtraj.interdrive.detector import SceneGeometry
    from langtraj.interdrive.detector.parts import Pair
    from langtraj.interdrive.judging import Judge, Judgement
    from langtraj.interdrive.targets.context import AgentHere, TargetContext
    from langtraj.interdrive.targets.target import BehaviourTarget
    from langtraj.scenario.model import Scenario

# ---------------------------------------------------------------------------------------------- parameters

Figure = Literal["metres", "deceleration"]
"""Which figure of a prompt's text a parameter takes (`PromptReading.metres`, `PromptReading.deceleration`)."""


@dataclass(frozen=True)
class Parameter:
    """One number a behaviour may be asked with ("with a 15 m gap": `gap`, in m): its default, the range it is
    accepted in (outside it the prompt is refused at load, `check`), and the figure of the text it is read from."""

    name: str
    unit: str
    default: float
    low: float
    high: float
    reads: Figure
    doc: str = ""

    def check(self, value: float, behaviour: str) -> float:
        """`value` when it lies in [low, high]; else a one-line InputError saying the range."""
        if not (math.isfinite(value) and self.low <= value <= self.high):
            raise InputError(
                f"{behaviour}'s {self.name} {value:g} {self.unit} is outside {self.low:g} to {self.high:g} "
                f"{self.unit}{f' ({self.doc})' if self.doc else ''}",
                where=self.name,
            )
        return value

    def describe(self, value: float | None) -> str:
        """ "gap 15 m", or "gap 10 m (default)" when the text gave none."""
        if value is None:
            return f"{self.name} {self.default:.3g} {self.unit} (default)"
        return f"{self.name} {value:.3g} {self.unit}"


# ---------------------------------------------------------------------------------------------- steering


SteerKind = Literal["route", "station", "speed", "lead", "avoid"]

ROUTE_WEIGHT = 1.0
"""Per m^2 off the target's path."""
REACH_WEIGHT = 1 / 5.0**2
"""Per m^2 short of a goal station."""
HOLD_WEIGHT = 1 / 2.0**2
"""Per m^2 past a stop or conflict point."""


@dataclass(frozen=True)
class Steer:
    """One steering term a behaviour asks for over simulated steps `first` ... `last` (1 = the first simulated step):
    on its `route` (off it costs `weight` per m^2), at a `station` along it (`mode` "reach": not short of `value`
    m; "hold": not past it), at a `speed` of `value` m/s, a `lead` of `value` m ahead of the other agent along the
    path (`mode` as for a station), or clear of the other agent (`avoid`, `value` m of buffer). `weight` None is the
    guidance library's weight for the kind (speed, avoid). `guidance.steering` makes each a cost on the plan steps
    of a replan (docs/simulation.md, 'Prompts that steer')."""

    kind: SteerKind
    value: float = 0.0
    first: int = 1
    last: int = FUTURE_STEPS
    weight: float | None = None
    mode: Literal["reach", "hold"] = "reach"


def steps(seconds: float) -> int:
    """Simulated steps in `seconds`."""
    return round(seconds / STEP_SECONDS)


def route(first: int = 1, last: int = FUTURE_STEPS, weight: float = ROUTE_WEIGHT) -> list[Steer]:
    return [Steer("route", 0.0, first, last, weight)]


def station(value: float, mode: Literal["reach", "hold"], first: int, last: int, weight: float) -> list[Steer]:
    return [Steer("station", float(value), first, last, weight, mode)]


def speed(value: float, first: int, last: int = FUTURE_STEPS) -> list[Steer]:
    return [Steer("speed", max(float(value), 0.0), first, last)]


def lead(value: float, mode: Literal["reach", "hold"], first: int, last: int, weight: float) -> list[Steer]:
    return [Steer("lead", float(value), first, last, weight, mode)]


def avoid(buffer: float) -> list[Steer]:
    return [Steer("avoid", float(buffer))]


# ---------------------------------------------------------------------------------------------- the interface

PairRuns = Callable[["SceneGeometry", int, int], "list[Pair]"]


class BehaviourKind(ABC):
    """One behaviour (see the module docstring). Subclasses set the class attributes and implement `target` and
    `steer`; a pair behaviour sets `pair_runs`, and one judged by numbers overrides `judge`."""

    name: ClassVar[str]
    spec: ClassVar[BehaviourSpec]
    """How it is worded and judged by the labelers (`interdrive.behaviour.BehaviourSpec`)."""
    words: ClassVar[tuple[str, ...]] = ()
    """The reader's regular expressions over the normalised prompt (`interdrive.reader.words` has the word
    classes; a named group `other` marks the other agent, `agent` a request's object)."""
    word_rank: ClassVar[float] = 100.0
    """Where its words come in the reader's rule order, which breaks ties between equally long matches (a kind whose
    phrases end with another's words comes first: overtaking and cutting in before cutting in)."""
    subsumes: ClassVar[tuple[str, ...]] = ()
    """Kinds that, asked with this one, are part of it ("pulls over and stops": stop)."""
    then: ClassVar[tuple[str, ...]] = ()
    """Kinds that may follow it in one clause, steered and judged after it ("turns left and then stops")."""
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    in_path: ClassVar[bool] = False
    """Whether the agent ends in the other agent's path (a cut-in, a braking lead, a pull-out, a red-light run): a
    planner driving the other that ignores it should hit it (`suites.calibration`)."""
    judged: ClassVar[Judge | None] = None
    """Its judge by numbers (`interdrive.judging`: `judge(scene, agent, other, asked)`), None where the labelers'
    facts alone judge it."""
    pair_runs: ClassVar[PairRuns | None] = None
    """The interaction detector's rule for one ordered pair judging a pair behaviour in a candidate's future
    (`sim.adherence`): the runs of its interaction type, or of its own subtype where the spec is `exact`."""

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"{self.name} has no parameter {name!r}")

    def asked(self, figures: Mapping[str, float | None]) -> dict[str, float]:
        """The value of each parameter from the text's figures (`Parameter.reads`), its default where the text gives
        none; a value outside its range raises (`Parameter.check`)."""
        out = {}
        for p in self.parameters:
            given = figures.get(p.reads)
            out[p.name] = p.default if given is None else p.check(float(given), self.name)
        return out

    @abstractmethod
    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        """Where the behaviour takes `agent` (toward `other` for a pair behaviour) at the scene's current step, with
        the parameters `asked`; raises `TargetUnavailable` with the reason where the scene gives none."""

    @abstractmethod
    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """The terms that steer the agent to `target`; `other_driven`: the model drives the other agent, so terms
        relative to where it actually drives (`lead`, `avoid`) are available."""

    def script(self, target: BehaviourTarget) -> Script | None:
        """The manoeuvre the behaviour executes exactly from its `target` (`scripts.Script`), or None where guidance
        alone steers it (by default)."""
        return None

    def at_trigger(self, target: BehaviourTarget) -> BehaviourTarget:
        """The target when a trigger the prompt gives starts the behaviour ("when @ego is within 20 m"): the moment
        is the prompt's, so a behaviour that otherwise waits a little first starts at once; unchanged by default."""
        return target

    def placed(self, target: BehaviourTarget, within_m: float | None = None) -> BehaviourTarget | None:
        """The target that keeps the agent where it can stage the behaviour, executed until a trigger the prompt gives
        starts it ("after 3 s": a cutter keeping its lead beside the other in its own lane, not moving across), from
        the behaviour's target at the start; with `within_m`, the bumper gap between the two at which the prompt's
        trigger starts it ("when @ego is within 20 m of @4"), a place that brings the other within it (a braking
        lead easing off until its follower is there). None where the kind keeps no such place (the agent is steered
        to keep its offset to the other instead, or, for a gap, driven as if unprompted: `sim.staging.keeping`)."""
        return None

    def ready(self, target: BehaviourTarget) -> str | None:
        """Why the behaviour should not start yet from `target`, derived from the agents as they are now (a cut-in
        that would need its agent to brake hard to let the other catch up; a braking lead with its follower far
        behind), or None when it may start now. A staged behaviour waits until it may (`sim.staging`); by default
        at once."""
        return None

    def natural(self, target: BehaviourTarget) -> str | None:
        """Why `suggest` should not offer the staging of `target` although the scene allows it and it may start (a
        cut-in whose agent would have to drop back hard for the other to come up: not how a cut-in comes about), or
        None; by default every feasible, ready target is."""
        return None

    def judge(self, scene: Scenario, agent: int, other: int | None, asked: Mapping[str, float]) -> Judgement | None:
        """The realised numbers beside the asked ones on a played scene (`judged`); None where the behaviour is judged
        by the labelers' facts alone. `asked` holds its parameters by name (`asked`); another name is an
        InputError."""
        if self.judged is None:
            return None
        unknown = sorted(set(asked) - {p.name for p in self.parameters})
        if unknown:
            known = ", ".join(p.name for p in self.parameters) or "none"
            raise InputError(f"unknown asked values {', '.join(unknown)}; known: {known}", where="asked")
        if other is None:
            raise InputError(f"{self.name} is judged toward another agent", where="asked")
        return self.judged(scene, agent, other, asked)


_INSTANCES: dict[str, BehaviourKind] = {}


def kind(name: str, where: str | None = None) -> BehaviourKind:
    """The behaviour called `name` (one instance per registered class); an unknown name raises InputError listing
    the known."""
    if str(name) not in KINDS.names():
        raise InputError(f"unknown behaviour {str(name)!r}; known: {', '.join(names())}", where=where)
    cls = KINDS.get(str(name), where)
    found = _INSTANCES.get(str(name))
    if type(found) is not cls:
        found = _INSTANCES[str(name)] = cls()
    return found


def register(cls: type[BehaviourKind]) -> type[BehaviourKind]:
    """Class decorator adding a behaviour to `KINDS` (listed after the shipped ones: `behaviour.names`)."""
    return KINDS.register(cls)
