"""The behaviour registry: every shipped behaviour is one registered module declaring its words, parameters, target,
steering and judges; and a new behaviour is one class in one file, then read, placed, steered and judged like the
shipped ones (docs/design.md, 'Behaviours')."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import replace

import numpy as np
import pytest
from scenario_builders import two_lane_road

from langtraj.errors import InputError
from langtraj.guidance.costs import TargetSpeedCost
from langtraj.guidance.route import RouteCost
from langtraj.guidance.steering import Steering
from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.behaviour import BEHAVIOURS, KINDS, SHIPPED, Behaviour, BehaviourSpec, names
from langtraj.interdrive.behaviours import BehaviourKind, kind, register
from langtraj.interdrive.behaviours.base import Steer, route, speed
from langtraj.interdrive.judging import Judgement, Measure
from langtraj.interdrive.reader import read_prompt
from langtraj.interdrive.reader.words import verb
from langtraj.interdrive.targets import AgentHere, BehaviourTarget, TargetContext, derive_target, feasibility
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import StateField
from langtraj.sim.prompts import read_prompts


def test_every_shipped_behaviour_is_registered_in_the_order_alternatives_are_listed():
    """Whichever module is imported first (a test importing `brake_hard`'s constants before anything asked the
    registry), the alternatives are listed in the shipped order."""
    assert set(KINDS.names()) >= set(SHIPPED)
    assert names()[: len(SHIPPED)] == SHIPPED and tuple(BEHAVIOURS)[: len(SHIPPED)] == SHIPPED
    for name in SHIPPED:
        behaviour = kind(name)
        assert behaviour.spec.behaviour == name and behaviour.words, name
        assert (behaviour.pair_runs is not None) == behaviour.spec.is_pair, name
        assert Behaviour(name) is getattr(Behaviour, name.upper())
    assert [p.name for p in kind("cut_in").parameters] == ["gap"]
    assert [p.name for p in kind("brake_hard").parameters] == ["deceleration"]


def test_an_unknown_behaviour_is_a_one_line_error_listing_the_known():
    with pytest.raises(InputError, match="unknown behaviour 'cutin'; known: turn_left, "):
        kind("cutin")


# ---------------------------------------------------------------------------------------------- a toy behaviour

CREEP_SPEED = 1.5
"""How fast a creeping agent moves (m/s)."""


class Creep(BehaviourKind):
    """A toy behaviour, declared here in one class as a user would in one module: "@12 creeps forward" (at 1.5 m/s
    along its lane), judged by the labelers' moving-slowly label and by its mean speed."""

    name = "creep"
    spec = BehaviourSpec(Behaviour("creep"), "@{agent} creeps forward", "creep forward", "moving_slowly")
    words = (rf"\b{verb('creep', 'inch')}\s+(?:forward|ahead|along)\b",)

    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        return BehaviourTarget(
            agent.track_id, Behaviour(self.name), ctx.ahead(agent), f"its lane ahead at {CREEP_SPEED} m/s",
            speed=CREEP_SPEED, current_speed=agent.here.speed,
        )  # fmt: skip

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        return speed(float(target.speed or 0.0), 1) + route(weight=0.25)

    def judge(self, scene: Scenario, agent: int, other: int | None, asked: Mapping[str, float]) -> Judgement:
        row, c = scene.agents.index_of(agent), scene.current_index
        xy = scene.agents.states[row, c:, [StateField.X, StateField.Y]].T.astype(np.float64)
        mean = float(np.linalg.norm(xy[-1] - xy[0]) / (0.1 * (len(xy) - 1)))
        ok = abs(mean - CREEP_SPEED) <= 0.5
        measure = Measure("speed", "m/s", CREEP_SPEED, mean, 0.5, ok)
        return Judgement(ok, (measure,), "" if ok else f"mean speed {mean:.1f} m/s", None, None)


@pytest.fixture
def creep() -> Iterator[type[Creep]]:
    register(Creep)
    try:
        yield Creep
    finally:
        KINDS.unregister("creep")


def _creeping(speed_after: float) -> Scenario:
    """@1 at 10 m/s braking to `speed_after` within 1 s and keeping it; @2 far behind."""
    scene = two_lane_road([(0, 0, 10), (-80, 0, 10)])
    states = scene.agents.states.copy()
    t = (np.arange(scene.num_steps) - scene.current_index) * 0.1
    v = np.where(t <= 0, 10.0, np.maximum(10.0 - 9.0 * t, speed_after))
    x = np.concatenate([[0.0], np.cumsum(v[1:] * 0.1)]) - float(np.sum(v[1 : scene.current_index + 1] * 0.1))
    states[0, :, StateField.X], states[0, :, StateField.VX] = x, v
    return replace(scene, agents=replace(scene.agents, states=states))


def test_a_toy_behaviour_in_one_class_is_read_placed_steered_and_judged(creep):
    assert "creep" in BEHAVIOURS and Behaviour("creep") in list(Behaviour)
    reading = read_prompt("@1 creeps forward")  # read
    assert (reading.behaviour, reading.agent) == ("creep", 1)
    assert reading.describe() == 'read as: @1 creep ("creeps forward")'
    assert read_prompts(["@1 creeps forward"])[0].behaviour == "creep"

    scene = _creeping(1.5)
    index = MapIndex.build(scene.road_map)
    target = derive_target(scene, 1, Behaviour("creep"), index)  # placed
    assert target.speed == 1.5 and len(target.path) > 10
    assert feasibility(scene, 1, Behaviour("creep"), index).status == "feasible"

    terms = Steering.of(target, (0.0, 0.0, 0.0), {1: 0}).terms(0, 80)  # steered
    assert isinstance(terms[0].cost, TargetSpeedCost) and isinstance(terms[1].cost, RouteCost)

    facts = AdherenceChecker.build(scene, logged=True).facts(scene)  # judged: by the labelers, and by numbers
    assert reading.followed(facts) is True
    assert kind("creep").judge(scene, 1, None, {}).happened
    fast = _creeping(6.0)
    assert reading.followed(AdherenceChecker.build(fast, logged=True).facts(fast)) is False
    assert not kind("creep").judge(fast, 1, None, {}).happened


def test_the_toy_behaviour_leaves_with_its_registration(creep):
    KINDS.unregister("creep")
    assert read_prompt("@1 creeps forward").behaviour is None
    register(Creep)


@pytest.mark.parametrize(
    ("text", "line"),
    [
        ("@52 cuts in front of @7 with a 15 m gap", 'read as: @52 cut_in @7, gap 15 m ("cuts in front of @7")'),
        ("@52 cuts in front of @7", 'read as: @52 cut_in @7, gap 10 m (default) ("cuts in front of @7")'),
        (
            "@738 brakes hard at 0.5 g in front of @7",
            'read as: @738 brake_hard @7, deceleration 4.9 m/s^2 ("brakes hard at 0.5 g in front of @7")',
        ),
    ],
)
def test_read_as_shows_every_parameter_read_or_defaulted(text, line):
    assert read_prompt(text).describe() == line


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("@52 cuts in front of @7 with a 50 m gap", "cut_in's gap 50 m is outside 2 to 30 m"),
        ("@738 brakes hard at 12 m/s^2 in front of @7", "brake_hard's deceleration 12 m/s^2 is outside 3 to 10 m/s^2"),
        ("@738 tailgates @7 at 5 m", "'5 m' is not read: tailgate takes no such figure (its parameters: none)"),
    ],
)
def test_a_parameter_out_of_range_or_not_taken_is_refused_in_one_line(text, message):
    with pytest.raises(InputError) as raised:
        read_prompts([text])
    assert message in str(raised.value) and "\n" not in str(raised.value)
    assert read_prompts([text], strict=False)[0].read  # judging a played episode reads it all the same
