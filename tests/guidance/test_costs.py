"""Each guidance cost: its value on a constructed case and the direction its gradient pushes."""

from __future__ import annotations

import pytest
import torch

from langtraj.errors import InputError
from langtraj.guidance import (
    GUIDANCE,
    CollisionCost,
    GoalCost,
    GuidanceTerm,
    KeepLaneCost,
    NoCollisionCost,
    OnRoadCost,
    TargetSpeedCost,
)

from .helpers import cost_gradient, make_scene, standing

# A straight road along x: the lower edge runs east (road on its left, y > -2), the upper one west.
ROAD = [[[-50.0, -2.0], [50.0, -2.0]], [[50.0, 6.0], [-50.0, 6.0]]]
LANE = [[[-50.0, 0.0], [0.0, 0.0]], [[0.0, 0.0], [50.0, 0.0]]]


def test_the_registry_lists_the_ten_costs_and_returns_their_classes():
    assert GUIDANCE.names() == (
        "collision", "no_collision", "goal", "target_speed", "on_road", "keep_lane", "headway", "route", "station",
        "lead",
    )  # fmt: skip
    assert GUIDANCE.get("goal") is GoalCost
    with pytest.raises(InputError, match="unknown guidance cost 'nope'"):
        GUIDANCE.get("nope")


def test_collision_pulls_only_the_adversary_towards_the_target():
    scene = make_scene(3)
    states = standing([[0.0, 0.0], [10.0, 0.0], [5.0, 5.0]])
    cost = CollisionCost(adversary=0, target=1)
    value, grad = cost_gradient(cost, states, scene)
    assert value.item() == pytest.approx(10.0, abs=1e-3)
    assert (-grad[0, 0, :, 0] > 0).all()  # a descent step moves the adversary towards +x, the target
    assert grad[0, 1:].abs().max() == 0  # the target (and the bystander) get nothing
    assert cost.agents(3).tolist() == [True, False, False]


def test_collision_until_contact_ignores_the_steps_after_the_first_contact():
    scene = make_scene(2)
    states = standing([[0.0, 0.0], [10.0, 0.0]], steps=6)
    states[0, 0, :, 0] = torch.tensor([0.0, 5.0, 9.5, 5.0, 0.0, 0.0])  # touches at step 2, then backs off
    plain, _ = cost_gradient(CollisionCost(0, 1), states, scene)
    value, grad = cost_gradient(CollisionCost(0, 1, until_contact=True), states, scene)
    assert value.item() == pytest.approx((10 + 5 + 0.5) / 6, abs=1e-3)
    assert value.item() < plain.item()
    assert grad[0, 0, 3:].abs().max() == 0


def test_no_collision_pushes_overlapping_agents_apart_with_the_papers_value():
    scene = make_scene(2, size=(4.5, 2.0))
    states = standing([[0.0, 0.0], [0.0, 1.5]])  # side by side, disk radii 1 + 1 > 1.5
    value, grad = cost_gradient(NoCollisionCost(), states, scene)
    # Each ordered pair: mean overlap 1 - 1.5 / 2 = 0.25; two pairs among N = 2 agents.
    assert value.item() == pytest.approx(2 * 0.25 / 4, abs=1e-4)
    assert (-grad[0, 0, :, 1] < 0).all() and (-grad[0, 1, :, 1] > 0).all()


def test_no_collision_uses_disks_along_the_length_and_ignores_clear_pairs():
    scene = make_scene(2, size=(4.5, 2.0))
    nose_to_tail = standing([[0.0, 0.0], [4.0, 0.0]])  # end disks 1.5 m apart: overlapping
    assert NoCollisionCost()(nose_to_tail, scene).item() > 0
    assert NoCollisionCost(num_disks=1)(nose_to_tail, scene).item() == 0  # one central disk each: 4 m apart
    value, grad = cost_gradient(NoCollisionCost(), standing([[0.0, 0.0], [0.0, 2.5]]), scene)
    assert value.item() == 0 and grad.abs().max() == 0


def test_no_collision_covers_only_the_chosen_pairs_and_valid_agents():
    states = standing([[0.0, 0.0], [0.0, 1.5], [0.0, -1.5]])
    scene = make_scene(3)
    only_one = NoCollisionCost(0, others=[1])
    value, grad = cost_gradient(only_one, states, scene)
    assert value.item() == pytest.approx(0.25 / 4, abs=1e-4)  # one ordered pair among N = 2 agents
    assert grad[0, 2].abs().max() == 0
    assert only_one.agents(3).tolist() == [True, False, False]
    invalid = make_scene(3, valid=[True, True, False])
    assert NoCollisionCost()(states, invalid).item() == pytest.approx(2 * 0.25 / 4, abs=1e-4)


def test_no_collision_sums_the_pairs_with_the_sum_reduction_whatever_the_scenes_size():
    # Agents 0 and 1 overlap (mean overlap 0.25 each way); the others stand far apart.
    for count in (2, 5):
        states = standing([[0.0, 0.0], [0.0, 1.5]] + [[100.0 * k, 50.0] for k in range(1, count - 1)])
        scene = make_scene(count)
        summed, grad = cost_gradient(NoCollisionCost(reduction="sum"), states, scene)
        mean, mean_grad = cost_gradient(NoCollisionCost(), states, scene)
        assert summed.item() == pytest.approx(2 * 0.25, abs=1e-4)  # the two ordered pairs, undivided
        assert summed.item() == pytest.approx(mean.item() * count**2, rel=1e-6)
        assert torch.allclose(grad, mean_grad * count**2, atol=1e-6)


def _no_collision_by_hand(states, scene, slots, others, num_disks=5):
    """The paper's cost over every ordered pair and step, without the search's shortcuts."""
    size = scene.agent_size
    radius = size[:, 1] / 2
    reach = (size[:, 0] / 2 - radius).clamp(min=0.0)
    offsets = torch.linspace(-1.0, 1.0, num_disks)[None, :] * reach[:, None]  # [A, D]
    heading = torch.stack([torch.cos(states[..., 2]), torch.sin(states[..., 2])], dim=-1)  # [S, A, T, 2]
    disks = states[..., None, :2] + offsets[None, :, None, :, None] * heading[..., None, :]  # [S, A, T, D, 2]
    total = states.new_zeros(states.shape[0])
    for i in slots:
        for j in others:
            if i == j:
                continue
            gap = (disks[:, i, :, :, None] - disks[:, j, :, None, :]).norm(dim=-1).flatten(2).min(-1).values
            penalty = torch.relu(1.0 - gap / (radius[i] + radius[j]))  # [S, T]
            total = total + penalty.sum(-1) / (penalty > 0).sum(-1).clamp(min=1)
    return total / len(set(slots) | set(others)) ** 2


@pytest.mark.parametrize("slots, others", [(None, None), ([0, 3, 5], None), ([1, 2], [2, 4, 6, 7])])
def test_no_collision_search_matches_every_pair_and_step_by_hand(slots, others):
    # A crowded scene of queued and crossing cars plus one far away: the box and symmetry shortcuts of
    # the search must give the same value and gradient as summing every ordered pair and step.
    generator = torch.Generator().manual_seed(3)
    start = torch.rand(8, 2, generator=generator) * 12.0
    start[7] += 500.0
    velocity = torch.randn(8, 2, generator=generator) * 3.0
    steps = torch.arange(23)[:, None] * 0.1
    xy = start[None, :, None] + velocity[None, :, None] * steps + 0.5 * torch.randn(3, 8, 1, 2, generator=generator)
    heading = torch.rand(3, 8, 23, 1, generator=generator) * 6.0
    states = torch.cat([xy, heading, torch.zeros_like(heading)], dim=-1)
    scene = make_scene(8, size=(4.5, 2.0))
    value, grad = cost_gradient(NoCollisionCost(slots, others=others), states, scene)
    everyone = list(range(8))
    reference = states.clone().requires_grad_(True)
    expected = _no_collision_by_hand(reference, scene, slots or everyone, others or everyone)
    (expected_grad,) = torch.autograd.grad(expected.sum(), reference)
    assert value.min() > 0
    assert torch.allclose(value, expected.detach(), atol=1e-6)
    assert torch.allclose(grad, expected_grad, atol=1e-5)


def test_goal_pulls_the_chosen_step_towards_the_goal():
    scene = make_scene(2)
    states = standing([[0.0, 0.0], [1.0, 1.0]])
    value, grad = cost_gradient(GoalCost(0, (3.0, 4.0)), states, scene)
    assert value.item() == pytest.approx(5.0, abs=1e-3)
    step = -grad[0, 0, -1, :2]
    assert torch.allclose(step / step.norm(), torch.tensor([0.6, 0.8]), atol=1e-4)
    assert grad[0, 0, :-1].abs().max() == 0 and grad[0, 1].abs().max() == 0
    _, grad = cost_gradient(GoalCost(0, (3.0, 4.0), step=2), states, scene)
    assert grad[0, 0, 2, :2].abs().sum() > 0 and grad[0, 0, -1].abs().max() == 0
    with pytest.raises(InputError, match="step 10 is past the horizon of 10 steps"):
        GoalCost(0, (1.0, 1.0), step=10)(states, scene)


def test_target_speed_moves_the_speed_towards_the_target():
    scene = make_scene(2)
    states = standing([[0.0, 0.0], [5.0, 0.0]], speed=2.0)
    value, grad = cost_gradient(TargetSpeedCost(0, 5.0), states, scene)
    assert value.item() == pytest.approx(9.0)
    assert (-grad[0, 0, :, 3] > 0).all() and grad[0, 1].abs().max() == 0
    value, grad = cost_gradient(TargetSpeedCost([0, 1], [0.0, 2.0], start=5), states, scene)
    assert value.item() == pytest.approx(4.0)
    assert (-grad[0, 0, 5:, 3] < 0).all() and grad[0, 0, :5].abs().max() == 0 and grad[0, 1].abs().max() == 0


def test_on_road_pushes_off_road_points_back_and_leaves_the_middle_alone():
    scene = make_scene(3, road_edges=ROAD)
    states = standing([[0.0, -4.0], [0.0, 2.0], [0.0, -1.5]])  # off the road, mid-road, within the margin
    cost = OnRoadCost(margin=1.0)
    value, grad = cost_gradient(cost, states, scene)
    assert value.item() == pytest.approx((2.0 + 1.0) ** 2 + 0.5**2, abs=1e-3)
    assert (-grad[0, 0, :, 1] > 0).all() and (-grad[0, 2, :, 1] > 0).all()
    assert grad[0, 1].abs().max() == 0
    above = standing([[0.0, 7.0], [0.0, 2.0], [0.0, 2.0]])  # over the upper edge
    _, grad = cost_gradient(cost, above, scene)
    assert (-grad[0, 0, :, 1] < 0).all()
    assert OnRoadCost()(states, make_scene(3)).abs().max() == 0  # no road edges, no cost


def test_keep_lane_pulls_towards_the_nearest_lane_centre():
    scene = make_scene(2, lanes=LANE)
    states = standing([[10.0, 1.0], [-10.0, -0.5]])
    value, grad = cost_gradient(KeepLaneCost(), states, scene)
    assert value.item() == pytest.approx(1.0 + 0.25, abs=1e-4)
    assert (-grad[0, 0, :, 1] < 0).all() and (-grad[0, 1, :, 1] > 0).all()
    assert grad[..., 0].abs().max() < 1e-6  # along the lane nothing changes
    value, grad = cost_gradient(KeepLaneCost(1, end=3), states, scene)
    assert value.item() == pytest.approx(0.25, abs=1e-4)
    assert grad[0, 0].abs().max() == 0 and grad[0, 1, 3:].abs().max() == 0
    assert KeepLaneCost()(states, make_scene(2)).abs().max() == 0


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: CollisionCost(-1, 2), "collision: adversary must be a non-negative agent slot, got -1"),
        (lambda: CollisionCost(2, 2), "collision: adversary and target must be different agents, both are slot 2"),
        (lambda: CollisionCost(True, 2), "adversary must be a non-negative agent slot"),
        (lambda: NoCollisionCost([]), "no_collision: slots is empty"),
        (lambda: NoCollisionCost(others=[-3]), "others must be a non-negative agent slot"),
        (lambda: NoCollisionCost(num_disks=0), "num_disks must be an integer >= 1"),
        (lambda: NoCollisionCost(buffer=-1.0), "buffer must be finite and >= 0"),
        (lambda: NoCollisionCost(reduction="max"), "reduction must be 'mean' or 'sum', got 'max'"),  # type: ignore[arg-type]
        (lambda: GoalCost(0, (1.0,)), "goal must be two finite numbers"),
        (lambda: GoalCost(0, (1.0, float("nan"))), "goal must be two finite numbers"),
        (lambda: GoalCost(0, (1.0, 2.0), step=-1), "step must be >= 0"),
        (lambda: TargetSpeedCost(None, 3.0), "slots must name at least one agent"),
        (lambda: TargetSpeedCost(0, -1.0), "speed must be finite and >= 0"),
        (lambda: TargetSpeedCost([0, 1], [1.0]), "1 speeds for 2 slots"),
        (lambda: TargetSpeedCost(0, 1.0, start=5, end=5), "need 0 <= start < end"),
        (lambda: OnRoadCost(margin=float("inf")), "margin must be finite"),
        (lambda: KeepLaneCost(1.5), "slots must be a non-negative agent slot, got 1.5"),
        (lambda: GuidanceTerm(GoalCost(0, (0.0, 0.0)), weight=-1.0), "goal: weight must be finite and >= 0"),
        (lambda: GuidanceTerm(GoalCost(0, (0.0, 0.0)), schedule="sometimes"), "unknown schedule 'sometimes'"),
    ],
)
def test_bad_parameters_are_refused(make, message):
    with pytest.raises(InputError, match=message):
        make()


def test_slots_beyond_the_scene_and_badly_shaped_states_are_refused():
    scene = make_scene(2)
    states = standing([[0.0, 0.0], [1.0, 0.0]])
    with pytest.raises(InputError, match="collision: agent slot 5 is out of range for 2 agents"):
        CollisionCost(0, 5)(states, scene)
    with pytest.raises(InputError, match="keep_lane: agent slot 2 is out of range"):
        KeepLaneCost([2])(states, scene)
    with pytest.raises(InputError, match="states have 2 agents, the scene 3"):
        OnRoadCost()(states, make_scene(3))
    with pytest.raises(InputError, match="window start 20 is past the horizon"):
        TargetSpeedCost(0, 1.0, start=20)(states, scene)


def test_headway_pulls_a_follower_back_and_ignores_agents_beside_or_ahead():
    from langtraj.guidance.costs import HeadwayCost

    scene = make_scene(4)  # agent 0 leads (heading +x); 1 follows too close, 2 in the next lane, 3 ahead of it
    states = standing([[0.0, 0.0], [-4.0, 0.0], [-4.0, 3.5], [8.0, 0.0]])
    cost = HeadwayCost([1, 2, 3], leader=0, gap=2.0)
    value, grad = cost_gradient(cost, states, scene)
    assert value.item() > 0
    assert (grad[0, 1, :, 0] > 0).all()  # a descent step moves the follower back (-x), never forward
    assert grad[0, 1, :, 1].abs().max() == 0  # and not sideways
    assert grad[0, 2:].abs().max() == 0 and grad[0, 0].abs().max() == 0  # beside, ahead, the leader: nothing
    far = standing([[0.0, 0.0], [-20.0, 0.0], [-4.0, 3.5], [8.0, 0.0]])
    assert HeadwayCost([1, 2, 3], leader=0)(far, scene).item() == 0.0  # far enough behind: no cost
