"""What a scene can stage: every (agent, the ego, pair behaviour, parameters) the map and the agents' states allow at
the current step, each with the prompt that stages it, sorted by how natural it is.

A test engineer with a folder of scenes wants to know which safety-critical prompts each one supports before writing
a suite (`langtraj suggest`). The one answer to whether an agent can do a behaviour is `targets.feasibility`; this
module only chooses whom to ask (vehicles, and cyclists where the behaviour allows, valid at the current step within
the reach of each behaviour around the ego), which parameter values to try (a cut-in's gap, a braking lead's
deceleration), and ranks the answers by the change each asks of the agent and its distance to the ego. Only the
current step and the past are read, as `feasibility` reads them. See docs/testing.md, 'From a folder of scenes to a
report'.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour
from langtraj.interdrive.behaviours import kind
from langtraj.interdrive.targets import BehaviourTarget, CounterfactualConfig, TargetContext, feasibility
from langtraj.roads import MapIndex
from langtraj.roads.mission import mission_of
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType, StateField

EGO = "@ego"
"""How a prompt names the ego: the suites' and the env's placeholder, replaced by its track id at reset."""
RADIUS_M: Mapping[Behaviour, float] = {
    Behaviour.OVERTAKE_CUT_IN: 60.0,
    Behaviour.BRAKE_HARD: 60.0,
    Behaviour.TAILGATE: 60.0,
}
"""How far from the ego (centre to centre, m) an agent is asked about a behaviour: the targets' follower range of a
braking lead, a tailgater or an overtake (40 m bumper to bumper) with room for long vehicles; `DEFAULT_RADIUS_M`
else."""
DEFAULT_RADIUS_M = 80.0
"""The radius of the other behaviours: a cut-in from well ahead or behind, a crossing, a red light, a pull-out."""
CYCLISTS: frozenset[Behaviour] = frozenset({Behaviour.PULL_OUT, Behaviour.YIELD, Behaviour.GO_FIRST, Behaviour.FOLLOW})
"""The behaviours asked of cyclists too (a cyclist pulls out, yields, goes first, follows); the rest of vehicles."""
PARAMETER_VALUES: Mapping[Behaviour, tuple[float, ...]] = {
    Behaviour.CUT_IN: (5.0, 10.0, 15.0),
    Behaviour.OVERTAKE_CUT_IN: (5.0, 10.0, 15.0),
    Behaviour.BRAKE_HARD: (4.0, 6.0),
}
"""Per parameterised behaviour, the values of its parameter tried (its first, `BehaviourKind.parameters`: a gap in m;
a deceleration in m/s^2, Euro NCAP's braking-lead range); its default is the registry's."""
PROMPTS: Mapping[Behaviour, str] = {
    Behaviour.CUT_IN: "@{agent} cuts in front of @{other} with a {gap:g} m gap",
    Behaviour.OVERTAKE_CUT_IN: "@{agent} overtakes @{other} and cuts in front of it with a {gap:g} m gap",
    Behaviour.BRAKE_HARD: "@{agent} brakes hard at {deceleration:g} m/s^2 in front of @{other}",
}
"""The prompts of parameterised behaviours, the parameter written out (the reader reads it back); the others are the
vocabulary's own sentences (`BehaviourSpec.template`)."""
DISTANCE_WEIGHT_M = 10.0
"""In a score, this many metres from the ego count as much as 1 m/s of change asked of the agent."""
FOLLOW_HEADING = math.radians(45.0)
"""A follower heads the ego's way within this (rad), as the targets' followers do."""
GO_FIRST_MARGIN_S = 0.5
"""Going first gets the agent to the crossing this much earlier than the other (s; the targets' margin)."""
YIELD_MARGIN_S = 1.0
"""A yield lets the other agent get to the crossing this much earlier (s), for the change it asks."""


@dataclass(frozen=True)
class Staging:
    """One thing a scene can stage: `agent` doing `behaviour` toward `other` (the ego) with `parameters` (a cut-in's
    `gap`, a braking lead's `deceleration`; empty for the others), which `feasibility` calls feasible; `prompt`
    stages it (the ego written `@ego`), `reason` is the target's (where and when). `change` is how far the staging
    moves the agent from what it does now (m/s: the speed it needs against its own, a braking lead's deceleration),
    `distance_m` its distance to the ego, and `score` their sum with metres weighed by `DISTANCE_WEIGHT_M`: lower is
    more natural. `scene` is the file, `index` the scene in it, `window` the 9.1-s window cut (None: the scene as it
    is), as a suite's case names them."""

    scene: str
    index: int
    window: int | None
    scenario_id: str
    agent: int
    other: int
    behaviour: Behaviour
    prompt: str
    reason: str
    score: float
    change: float
    distance_m: float
    parameters: Mapping[str, float] = field(default_factory=dict)
    default: bool = True
    """Whether `parameters` are those `feasibility` takes when a prompt gives none."""

    @property
    def ego(self) -> int:
        return self.other

    @property
    def typed_prompt(self) -> str:
        """The prompt with the ego's track id in place of `@ego` (as the env reads it)."""
        return self.prompt.replace(EGO, f"@{self.other}")

    def to_json(self) -> dict[str, Any]:
        """JSON-ready, the numbers rounded to centimetres."""
        return {
            "scene": self.scene,
            "index": self.index,
            "window": self.window,
            "scenario_id": self.scenario_id,
            "ego": self.other,
            "agent": self.agent,
            "other": self.other,
            "behaviour": self.behaviour.value,
            "parameters": dict(self.parameters),
            "default": self.default,
            "prompt": self.prompt,
            "reason": self.reason,
            "score": round(self.score, 2),
            "change": round(self.change, 2),
            "distance_m": round(self.distance_m, 2),
        }


def pair_behaviours() -> tuple[Behaviour, ...]:
    """The behaviours toward another agent (`BehaviourSpec.is_pair`), in the vocabulary's order: what a scene can
    stage against the ego. Asked when needed, so that a kind added to the vocabulary is searched too."""
    return tuple(b for b, spec in BEHAVIOURS.items() if spec.is_pair)


def parse_behaviour(name: str) -> Behaviour:
    """The pair behaviour `name` names ("cut_in", "cut-in", "Cut in"); InputError with the closest names otherwise."""
    key = "_".join(name.strip().lower().replace("-", " ").split())
    known = [b.value for b in pair_behaviours()]
    if key in known:
        return Behaviour(key)
    if key in {b.value for b in Behaviour}:
        raise InputError(f"{name!r} is not a behaviour toward another agent; known: {', '.join(known)}")
    close = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
    hint = f"did you mean {close[0]!r}? " if close else ""
    raise InputError(f"unknown behaviour {name!r}; {hint}known: {', '.join(known)}")


def ego_of(scenario: Scenario, ego: int | None = None) -> int:
    """The ego's track id: `ego`, else the scene's self-driving car; InputError where there is none, the id is not
    in the scene, or the ego is not valid at the current step (nothing to stage against)."""
    agents, c = scenario.agents, scenario.current_index
    if ego is None:
        if scenario.sdc_index < 0:
            raise InputError(f"scene {scenario.scenario_id} has no self-driving car: name the ego", where="ego")
        ego = int(agents.ids[scenario.sdc_index])
    try:
        row = agents.index_of(ego)
    except KeyError:
        vehicles = agents.ids[(agents.types == AgentType.VEHICLE) & agents.valid[:, c]]
        some = ", ".join(map(str, vehicles[:8].tolist())) + (", ..." if len(vehicles) > 8 else "")
        raise InputError(
            f"no track {ego} in scene {scenario.scenario_id} (vehicles at the current step: {some or 'none'})",
            where="ego",
        ) from None
    if not agents.valid[row, c]:
        raise InputError(f"track {ego} is not valid at the current step of scene {scenario.scenario_id}", where="ego")
    return int(ego)


def suggest_stagings(
    scenario: Scenario,
    *,
    ego: int | None = None,
    behaviours: Iterable[Behaviour] | None = None,
    map_index: MapIndex | None = None,
    config: CounterfactualConfig | None = None,
    scene: str = "",
    index: int = 0,
    window: int | None = None,
) -> tuple[Staging, ...]:
    """Every staging of `behaviours` (default: every pair behaviour) toward the ego (`ego_of`) the scene allows,
    most natural first (`Staging.score`, then distance, agent, the vocabulary's order and the parameter). The map is
    indexed once (`map_index`, built when not given). `scene`, `index` and `window` only label the stagings.

    Targets read the ego's way as the route the env gives its planner (`roads.mission`), so what is offered is what
    an episode stages. Kinds the map always allows are listed where the scene stages them: a yield where the two
    ways cross (it can always wait, but a yield with no crossing stages nothing), following by an agent behind the
    ego heading its way."""
    ego = ego_of(scenario, ego)
    asked = pair_behaviours() if behaviours is None else tuple(dict.fromkeys(behaviours))
    for behaviour in asked:
        if not BEHAVIOURS[behaviour].is_pair:
            raise InputError(f"{behaviour.value!r} is not a behaviour toward another agent", where="behaviour")
    index_ = map_index if map_index is not None else MapIndex.build(scenario.road_map)
    scene_ = _Scene.of(scenario, ego)
    mission = mission_of(scenario, scenario.agents.index_of(ego), index_)  # the route its planner is given
    context = TargetContext(scenario, index_, config, {ego: mission.points})  # each agent's roads found once
    found: list[Staging] = []
    for behaviour in asked:
        values = PARAMETER_VALUES.get(behaviour, ())
        parameter = kind(behaviour).parameters[0] if values else None
        name, default = ("", 0.0) if parameter is None else (parameter.name, parameter.default)
        for row in scene_.candidates(behaviour):
            agent = int(scenario.agents.ids[row])
            for value in values or (None,):
                parameters = {} if value is None else {name: value}
                verdict = feasibility(
                    scenario, agent, behaviour, index_, other_id=ego, context=context, **parameters
                )  # fmt: skip
                if verdict.status != "feasible" or verdict.target is None or not scene_.stages(row, verdict.target):
                    continue
                change = _change(verdict.target, parameters)
                distance = float(scene_.distance[row])
                found.append(
                    Staging(
                        scene, index, window, scenario.scenario_id, agent, ego, behaviour,
                        prompt=prompt_text(behaviour, agent, parameters),
                        reason=verdict.target.reason,
                        score=change + distance / DISTANCE_WEIGHT_M,
                        change=change,
                        distance_m=distance,
                        parameters=parameters,
                        default=value is None or value == default,
                    )
                )  # fmt: skip
    order = {b: i for i, b in enumerate(pair_behaviours())}
    found.sort(key=lambda s: (round(s.score, 6), s.distance_m, s.agent, order[s.behaviour], *s.parameters.values()))
    return tuple(found)


def prompt_text(behaviour: Behaviour, agent: int, parameters: Mapping[str, float] | None = None) -> str:
    """The prompt that stages `behaviour` of `agent` toward the ego, its parameters written out."""
    if behaviour in PROMPTS and parameters:
        return PROMPTS[behaviour].format(agent=agent, other="ego", **parameters)
    return BEHAVIOURS[behaviour].text(agent, "ego")  # type: ignore[arg-type]


def count_by_behaviour(stagings: Sequence[Staging]) -> dict[str, int]:
    """How many stagings of each pair behaviour (every one named, zeros included), in the vocabulary's order."""
    return {b.value: sum(s.behaviour is b for s in stagings) for b in pair_behaviours()}


@dataclass(frozen=True)
class _Scene:
    """The agents at the current step, seen from the ego: who may be asked, and how far each is."""

    scenario: Scenario
    ego_row: int
    distance: np.ndarray
    along: np.ndarray
    """How far each agent's centre is ahead of the ego's along its heading (m)."""
    heading_gap: np.ndarray
    """Each agent's heading less the ego's, wrapped (rad)."""

    @classmethod
    def of(cls, scenario: Scenario, ego: int) -> _Scene:
        row = scenario.agents.index_of(ego)
        states = scenario.agents.states[:, scenario.current_index]
        xy = states[:, [StateField.X, StateField.Y]].astype(np.float64)
        heading = float(states[row, StateField.HEADING])
        offset = xy - xy[row]
        along = offset @ np.array([math.cos(heading), math.sin(heading)])
        gap = wrap_angle(states[:, StateField.HEADING].astype(np.float64) - heading)
        return cls(scenario, row, np.linalg.norm(offset, axis=1), along, gap)

    def candidates(self, behaviour: Behaviour) -> list[int]:
        """Rows of the agents asked about `behaviour`: valid vehicles (and cyclists, `CYCLISTS`) within its radius
        of the ego, nearest first."""
        agents, c = self.scenario.agents, self.scenario.current_index
        kinds = [AgentType.VEHICLE] + ([AgentType.CYCLIST] if behaviour in CYCLISTS else [])
        near = self.distance <= RADIUS_M.get(behaviour, DEFAULT_RADIUS_M)
        ok = agents.valid[:, c] & np.isin(agents.types, [int(k) for k in kinds]) & near
        ok[self.ego_row] = False
        rows = np.flatnonzero(ok)
        return rows[np.argsort(self.distance[rows], kind="stable")].tolist()

    def stages(self, row: int, target: BehaviourTarget) -> bool:
        """Whether a feasible target stages something now: a yield needs a crossing, a follower must be behind the
        ego heading its way, and a behaviour staged on the ego's live state must be ready to start
        (`BehaviourKind.ready`: no cut-in in front of a standing ego) and come about naturally (`BehaviourKind.natural`:
        no cut-in that must drop back hard first); every other feasible target does."""
        behaviour = kind(target.behaviour)
        if behaviour.in_path and (behaviour.ready(target) is not None or behaviour.natural(target) is not None):
            return False
        if target.behaviour is Behaviour.YIELD:
            return target.conflict is not None
        if target.behaviour is Behaviour.FOLLOW:
            return self.along[row] < 0.0 and abs(float(self.heading_gap[row])) <= FOLLOW_HEADING
        return True


def _change(target: BehaviourTarget, parameters: Mapping[str, float]) -> float:
    """How far a staging moves the agent from what it does now (m/s): the average speed its target needs against its
    current speed (a cut-in's, an overtake's, a tailgater's closing), the speed it drives at (through a red light,
    after pulling out), a braking lead's deceleration over a second, the speed a yield gives up or going first adds
    to be at the crossing in time, and a follower's speed against the ego's."""
    v = target.current_speed
    b = target.behaviour
    if b is Behaviour.BRAKE_HARD:
        assert target.deceleration is not None, "a braking lead's target says how hard it brakes"
        return float(target.deceleration)
    if b in (Behaviour.YIELD, Behaviour.GO_FIRST):
        if target.station_of_goal is None or target.other_eta is None:
            return 0.0
        if b is Behaviour.YIELD:  # slow enough to be there after the other
            return max(0.0, v - target.station_of_goal / (target.other_eta + YIELD_MARGIN_S))
        return max(0.0, target.station_of_goal / max(target.other_eta - GO_FIRST_MARGIN_S, 0.1) - v)
    if b is Behaviour.FOLLOW:
        return abs((target.other_speed or 0.0) - v)
    if b is Behaviour.PULL_OUT or target.settled_s is None or target.station_of_goal is None:
        return abs((target.speed if target.speed is not None else v) - v)
    return abs(target.station_of_goal / max(target.settled_s, 1e-6) - v)
