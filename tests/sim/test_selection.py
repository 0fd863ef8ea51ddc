"""Candidate selectors on constructed candidates: the joint choice, and each agent's own choice."""

import pytest
import torch

from langtraj.guidance import GuidanceScene
from langtraj.sim.selection import SELECTORS, chosen_states

STEPS = 10


def _scene(num_agents: int = 2) -> GuidanceScene:
    """A road along x between y = -5 and y = 5 (edges keep the road on their left)."""
    right_edge = torch.tensor([[-100.0, -5.0], [100.0, -5.0]])
    left_edge = torch.tensor([[100.0, 5.0], [-100.0, 5.0]])
    return GuidanceScene(
        road_edges=torch.stack([right_edge, left_edge]),
        lanes=torch.zeros(0, 2, 2),
        lane_valid=torch.zeros(0, 2, dtype=torch.bool),
        agent_size=torch.tensor([[4.0, 2.0]] * num_agents),
        agent_valid=torch.ones(num_agents, dtype=torch.bool),
    )


def _track(x0: float, y: float) -> torch.Tensor:
    """A straight drive along x at height y: states [T, 4]."""
    x = x0 + torch.arange(1, STEPS + 1, dtype=torch.float32)
    return torch.stack([x, torch.full_like(x, y), torch.zeros_like(x), torch.ones_like(x)], -1)


def test_chosen_states_takes_joint_and_per_agent_choices():
    states = torch.arange(3 * 2 * 2 * STEPS * 4, dtype=torch.float32).reshape(3, 2, 2, STEPS, 4)
    joint = chosen_states(states, torch.tensor([2, 0]))
    assert torch.equal(joint[0], states[2, 0]) and torch.equal(joint[1], states[0, 1])
    mixed = chosen_states(states, torch.tensor([[1, 2], [0, 1]]))
    assert torch.equal(mixed[0, 0], states[1, 0, 0]) and torch.equal(mixed[0, 1], states[2, 0, 1])
    assert torch.equal(mixed[1, 1], states[1, 1, 1])


def test_per_agent_keeps_each_agent_on_the_road_where_no_joint_candidate_does():
    # Candidate 0 has agent 0 off the road, candidate 1 agent 1: every joint choice leaves one off.
    on_a, off_a = _track(0.0, 0.0), _track(0.0, 8.0)
    on_b, off_b = _track(30.0, -1.0), _track(30.0, -9.0)
    states = torch.stack([torch.stack([off_a, on_b]), torch.stack([on_a, off_b])])[:, None]  # [M=2, R=1, A, T, 4]
    scene = _scene()
    assert SELECTORS.create("min_collision").select(states, scene, ()).shape == (1,)
    choice = SELECTORS.create("per_agent").select(states, scene, ())
    assert choice.tolist() == [[1, 0]]


def test_per_agent_refuses_a_candidate_that_collides_with_the_assembled_scene():
    # Agent 1's candidate 1 is on the road but drives through agent 0's candidate 0; its candidate 0 is
    # slightly closer to the edge (a small road cost) and clear of agent 0.
    a = _track(0.0, 0.0)
    b_clear, b_crash = _track(0.0, -4.5), _track(0.0, 0.5)
    states = torch.stack([torch.stack([a, b_clear]), torch.stack([a, b_crash])])[:, None]
    choice = SELECTORS.create("per_agent").select(states, _scene(), ())
    assert choice[0, 1] == 0
    road = SELECTORS.create("per_agent")
    road.collision_weight = 0.0  # without the overlap term the on-road but colliding candidate would win
    assert road.select(states, _scene(), ())[0, 1] == 1


def test_per_agent_keeps_the_joint_choice_when_nothing_is_gained():
    a, b = _track(0.0, 0.0), _track(30.0, 1.0)
    states = torch.stack([torch.stack([a, b]), torch.stack([a, b])])[:, None]
    joint = SELECTORS.create("min_collision").select(states, _scene(), ())
    choice = SELECTORS.create("per_agent").select(states, _scene(), ())
    assert choice.tolist() == [[int(joint[0])] * 2]


def _per_agent_by_trials(states: torch.Tensor, scene: GuidanceScene, weight: float) -> torch.Tensor:
    """The per-agent selection as first written: each agent's step scores every candidate by the on-road
    and no-collision costs of a whole assembled trial scene (the reference the table-based one must meet)."""
    from langtraj.guidance import NoCollisionCost, OnRoadCost

    m, r, a = states.shape[:3]
    joint = NoCollisionCost()(states.reshape(m * r, *states.shape[2:]), scene).reshape(m, r).argmin(0)
    choice = joint[:, None].expand(r, a).clone()
    road = OnRoadCost().per_agent(states.reshape(m * r, *states.shape[2:]), scene).reshape(m, r, a)
    agents = scene.agent_valid.nonzero()[:, 0].tolist()
    for agent in agents:
        trial = chosen_states(states, choice)[None].repeat(m, 1, 1, 1, 1)
        trial[:, :, agent] = states[:, :, agent]
        overlap = NoCollisionCost(agent)(trial.reshape(m * r, *states.shape[2:]), scene).reshape(m, r)
        cost = road[:, :, agent] + weight * overlap * len(agents) ** 2
        cost = cost + 1e-6 * (torch.arange(m)[:, None] != choice[None, :, agent])
        choice[:, agent] = cost.argmin(dim=0)
    return choice


def test_per_agent_chooses_as_scoring_every_assembled_trial_scene_would():
    from guidance.helpers import crowd

    edges = torch.tensor([[[-10.0, 2.0], [50.0, 2.0]], [[50.0, 18.0], [-10.0, 18.0]]])  # a road across the crowd
    for seed in range(3):
        states, scene = crowd(16, 4, 3, 30, seed=seed, road_edges=edges)
        selector = SELECTORS.create("per_agent")
        expected = _per_agent_by_trials(states, scene, selector.collision_weight)
        assert torch.equal(selector.select(states, scene, ()), expected)
        assert torch.equal(selector.select(states, scene.with_road_field(), ()), expected)


def _prompted_case() -> tuple[torch.Tensor, torch.Tensor]:
    """Candidates [M=2, R=1, A=2, T, 4] and their `first` [M, R, A]: agent 0's candidate 1 follows its prompt
    (first = 0) but runs nearer the road edge; its candidate 0 does not (first = 1). Agent 1 is not prompted."""
    a_keep, a_follow = _track(0.0, 0.0), _track(0.0, 3.5)
    b_on, b_edge = _track(30.0, 0.0), _track(30.0, 4.5)
    states = torch.stack([torch.stack([a_keep, b_on]), torch.stack([a_follow, b_edge])])[:, None]
    return states, torch.tensor([[[1.0, 0.0]], [[0.0, 0.0]]])


def _per_agent_choice(choice: torch.Tensor, num_agents: int) -> list[list[int]]:
    """A selector's choice ([R] joint or [R, A] per agent) as each rollout's candidate per agent."""
    return (choice[:, None].expand(-1, num_agents) if choice.dim() == 1 else choice).tolist()


def test_a_prompted_agents_adhering_candidate_comes_first_then_road_and_collisions():
    # Agent 1 is not prompted (first = 0 for both) and keeps the road-and-collision choice.
    states, first = _prompted_case()
    scene = _scene()
    assert SELECTORS.create("per_agent").select(states, scene, ()).tolist() == [[0, 0]]
    assert SELECTORS.create("per_agent").select(states, scene, (), first).tolist() == [[1, 0]]


@pytest.mark.parametrize("name", SELECTORS.names())
def test_every_selector_takes_the_adhering_candidate_of_a_prompted_agent(name):
    states, first = _prompted_case()
    choice = SELECTORS.create(name).select(states, _scene(), (), first)
    assert _per_agent_choice(choice, 2)[0][0] == 1


@pytest.mark.parametrize("name", SELECTORS.names())
def test_every_selector_chooses_as_without_first_when_no_agent_is_prompted(name):
    from guidance.helpers import crowd

    states, scene = crowd(5, 4, 3, 20, seed=1)
    selector = SELECTORS.create(name)
    alone = selector.select(states, scene, ())
    assert torch.equal(selector.select(states, scene, (), torch.zeros(states.shape[:3])), alone)


def test_first_takes_the_least_missing_candidate_and_candidate_0_among_equals():
    states = torch.stack([_track(0.0, 0.0)[None, None].expand(1, 2, STEPS, 4)] * 3)  # [M=3, R=1, A=2, T, 4]
    scene = _scene()
    first = SELECTORS.create("first")
    assert first.select(states, scene, ()).tolist() == [0]
    misses = torch.tensor([[[1.0, 0.0]], [[0.5, 0.25]], [[0.0, 0.5]]])  # sums 1, 0.75, 0.5: candidate 2
    assert first.select(states, scene, (), misses).tolist() == [2]
    equal = torch.tensor([[[1.0, 0.0]], [[0.0, 0.0]], [[0.0, 0.0]]])  # candidates 1 and 2 miss nothing
    assert first.select(states, scene, (), equal).tolist() == [1]
    assert first.select(states, scene, (), torch.zeros(3, 1, 2)).tolist() == [0]
