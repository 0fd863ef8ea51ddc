"""A LangTraj simulation's hard constraints and held parked cars, end to end with the shipped checkpoint on a
constructed straight road: a car guided off the road stays on it with the projection, and a car parked at the kerb
stands still while the others drive."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from scenario_builders import two_lane_road

from langtraj.guidance import GuidanceTerm
from langtraj.guidance.costs import GoalCost
from langtraj.guidance.projection import HardConstraints
from langtraj.metrics.features import SceneMap
from langtraj.metrics.road import distance_to_road_edge
from langtraj.model.checkpoint import load_model
from langtraj.scenario import Scenario
from langtraj.sim.checkpoints import shipped_checkpoint
from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import simulate
from langtraj.sim.parked import parked_in_history
from langtraj.sim.policies import LangTrajPolicy, hard_constraints
from langtraj.sim.world import SimWorld

PARKED_ID = 4


def straight_road(parked: bool = True) -> Scenario:
    """Three cars at 10 m/s on the two-lane road and, with `parked`, a fourth standing at the kerb (y = -0.7) all
    through the log."""
    starts = [(0.0, 0.0, 10.0), (-25.0, 0.0, 10.0), (-10.0, 3.5, 10.0)] + ([(40.0, -0.7, 0.0)] if parked else [])
    return two_lane_road(starts)


@pytest.fixture(scope="module")
def shipped():
    return load_model(shipped_checkpoint())


def worst_offroad(scenario: Scenario, result, agent: int) -> float:
    """The largest box-corner distance past the road edge (m, WOSAC's geometry) of `agent` over every rollout."""
    edges = SceneMap.from_scenario(scenario).road_edges
    track = result.world.states[:, agent, scenario.current_index + 1 :]  # [R, T, StateField]
    ones = np.ones(track.shape[:2])
    x, y, heading = track[..., 0], track[..., 1], track[..., 3]
    return float(distance_to_road_edge(edges, x, y, 0 * ones, heading, 4.5 * ones, 2.0 * ones, ones, ones > 0).max())


def test_a_car_guided_off_the_road_stays_on_it_with_the_hard_constraints(shipped):
    scenario = straight_road(parked=False)
    model, data = shipped
    off_road = (GuidanceTerm(GoalCost(0, (60.0, -8.0)), weight=20.0),)  # pulls the first car off the road
    runs = {}
    for name, constraints in (("free", None), ("projected", HardConstraints())):
        policy = LangTrajPolicy(model, data, SimRequest(hard_constraints=0), terms=off_road, constraints=constraints)
        runs[name] = worst_offroad(scenario, simulate(scenario, policy, SimConfig(rollouts=2, seed=0)), 0)
    assert runs["free"] > 0.5  # the guidance drives its box half a metre and more past the edge ...
    assert runs["projected"] < 0.0  # ... and the projection keeps all of it on the road


def test_a_parked_car_stands_still_when_held(shipped):
    scenario = straight_road()
    parked = parked_in_history(scenario)
    assert parked.tolist() == [False, False, False, True]
    model, data = shipped
    result = simulate(
        scenario, LangTrajPolicy(model, data, SimRequest(hold_parked=True)), SimConfig(rollouts=2, seed=0)
    )
    track = result.world.states[:, 3, scenario.current_index :]
    assert np.allclose(track[..., :2], track[:, :1, :2], atol=1e-4)
    assert np.all(track[:, 1:, 4:6] == 0)  # no velocity
    # A prompt that names it lets the model drive it.
    policy = LangTrajPolicy.from_request(scenario, SimRequest(prompts=(f"@{PARKED_ID} speeds up",), hold_parked=True))
    assert policy.held_slots(scenario, result.world, ()) == ()


def test_requests_turn_the_projection_off_or_on_at_a_number_of_steps():
    assert hard_constraints(0, 5) is None
    assert hard_constraints(2, 5) == HardConstraints(steps=2)
    with pytest.raises(Exception, match="--hard-constraints"):
        hard_constraints(6, 5)


def test_a_kept_plan_offered_again_is_projected_like_a_fresh_candidate(shipped):
    """The candidate a prompted replan makes of the plan it executed (`PromptReplans.offer_kept_plans`) is kept on
    the road by the hard constraints as the sampled ones are, and its unprojected self is offered beside it."""
    from langtraj.model.features import collate_scenes

    scenario = straight_road(parked=False)
    model, data = shipped
    policy = LangTrajPolicy(model, data, constraints=HardConstraints())
    world = SimWorld(scenario, policy.drives(scenario, np.arange(3)), 1)
    state = policy.reset(world, 0)
    batch = collate_scenes([policy._sample(world, state, world.start, 0)])
    actions = torch.zeros(1, len(world.driven), model.config.num_actions, 2)
    actions[0, 0, :2, 1], actions[0, 0, 2:4, 1] = -0.35, 0.35  # the first car moves right, off the road (edge at -1.75)
    exempt = policy._exempt(state, batch.current_state)
    states, made = policy._realiser(state, batch, torch.zeros(1, len(world.driven)), exempt)(actions)
    assert states.shape[:2] == made.shape[:2] == (2, 1)  # projected, then as planned
    lowest = states[:, 0, 0, :, 1].amin(-1)  # scene frame: the first car starts at the origin, heading along x
    assert -5.0 < lowest[1] < -3.0  # as planned it leaves the road ...
    assert lowest[0] > -1.75 + 1.0 - 0.3  # ... projected, its side stays near the edge, not past it
    assert torch.equal(made[1], actions)


class _Mixed:
    """A selector taking the agent in slot `cruising` from candidate 0 and every other agent from candidate 1."""

    def __init__(self, cruising: int):
        self.cruising = cruising

    def select(self, states, scene, terms, first=None):
        choice = torch.ones(states.shape[1:3], dtype=torch.long)
        choice[:, self.cruising] = 0
        return choice


@pytest.mark.parametrize("on_choice", [True, False])
def test_a_plan_assembled_from_two_candidates_is_projected_apart(shipped, monkeypatch, on_choice):
    """Each candidate keeps its agents apart, but a plan assembled agent by agent from two candidates need not: the
    first car cruising (candidate 0) and the car 25 m behind it gaining 0.8 m/s^2 on it (candidate 1, where the
    first car does the same). With `on_choice` the executed plan is projected again and the second car is held back."""
    scenario = straight_road(parked=False)
    model, data = shipped
    policy = LangTrajPolicy(model, data, SimRequest(candidates=2), constraints=HardConstraints(on_choice=on_choice))
    world = SimWorld(scenario, policy.drives(scenario, np.arange(3)), 1)
    state = policy.reset(world, 0)
    first, second = (int(np.flatnonzero(world.driven == row)[0]) for row in (0, 1))  # model slots of the two cars
    state.selector = _Mixed(first)
    physical = torch.zeros(2, 1, 3, model.config.num_actions, 2)
    physical[1, 0, [first, second], :, 0] = 0.8  # candidate 1: the two cars accelerate alike

    def sample(batch, num_samples, **_):
        x = model.to_units(physical)
        return torch.stack([model.rollout(batch, x[i]) for i in range(num_samples)]), model.from_units(x)

    monkeypatch.setattr(model, "sample", sample)
    plan = policy.plan(world, state, world.start, model.horizon_steps)  # [R, A, T, 4], world frame
    gap = plan[0, first, :, 0] - plan[0, second, :, 0]  # the two cars' centres along the road
    if on_choice:
        assert gap.min() > 4.5 - 0.3  # a car length apart, whatever each candidate did
    else:
        assert gap.min() < 4.5 - 1.0  # the assembled plan drives the second car into the first
