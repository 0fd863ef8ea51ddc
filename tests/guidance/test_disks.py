"""The disk geometry behind the no-collision cost: the pruning test never drops an overlap, and the
table of every two agents' candidates holds what `NoCollisionCost` gives each combination."""

from __future__ import annotations

import torch

from langtraj.guidance import NoCollisionCost
from langtraj.guidance.disks import DiskLayout, candidate_overlaps

from .helpers import crowd


def test_may_overlap_never_drops_a_pair_whose_disks_overlap_and_drops_most_that_do_not():
    states, scene = crowd(30, 1, 1, 40, seed=0)
    layout = DiskLayout.of(scene, 5, states)
    i, j = torch.triu(torch.ones(30, 30, dtype=torch.bool), diagonal=1).nonzero(as_tuple=True)
    t = torch.arange(40)
    i, j, t = i.repeat_interleave(40), j.repeat_interleave(40), t.repeat(len(i))
    state_i, state_j = states[0, 0, i, t], states[0, 0, j, t]
    penalty = layout.penalty(state_i, state_j, i, j, 0.0)
    kept = layout.may_overlap(state_i, state_j, i, j, 0.0)
    assert (penalty > 0).sum() > 100
    assert kept[penalty > 0].all()
    assert (~kept[penalty == 0]).float().mean() > 0.9


def test_the_candidate_table_holds_each_combinations_no_collision_pair_cost():
    m, r, a = 3, 2, 12
    states, scene = crowd(a, m, r, 30, seed=1)
    overlaps = candidate_overlaps(states, scene)
    assert overlaps.table.shape == (r, len(overlaps.first), m, m) and (overlaps.table > 0).sum() > 10
    listed = {(int(i), int(j)): q for q, (i, j) in enumerate(zip(overlaps.first, overlaps.second, strict=True))}
    for i in range(a - 1):  # the padding agent is never listed
        for j in range(i + 1, a - 1):
            for mi in range(m):
                for mj in range(m):
                    joint = states[mi].clone()
                    joint[:, j] = states[mj, :, j]
                    # One ordered pair among N = 2 agents: the pair's cost divided by 4.
                    expected = NoCollisionCost(i, others=[j])(joint, scene) * 4
                    got = overlaps.table[:, listed[(i, j)], mi, mj] if (i, j) in listed else torch.zeros(r)
                    assert torch.allclose(got, expected, atol=1e-6), (i, j, mi, mj)


def test_agents_that_never_come_close_leave_the_table_empty_and_cost_nothing():
    states, scene = crowd(4, 2, 2, 20, seed=3)
    states[..., :2] = states[..., :2] + torch.arange(4)[None, None, :, None, None] * 100.0  # 100 m apart
    overlaps = candidate_overlaps(states, scene)
    assert overlaps.table.shape == (2, 0, 2, 2) and overlaps.first.numel() == 0
    value = NoCollisionCost()(states[0], scene)
    assert torch.equal(value, torch.zeros(2))


def test_the_penalty_equals_the_least_distance_between_disk_centres_in_value_and_gradient():
    states, scene = crowd(30, 1, 1, 20, seed=4)
    layout = DiskLayout.of(scene, 5, states)
    i, j = torch.triu(torch.ones(30, 30, dtype=torch.bool), diagonal=1).nonzero(as_tuple=True)
    t = torch.arange(20).repeat(len(i))
    i, j = i.repeat_interleave(20), j.repeat_interleave(20)

    def reference(state_i, state_j):  # every disk centre, every difference vector
        def centres(state, offsets):
            heading = torch.stack([torch.cos(state[:, 2]), torch.sin(state[:, 2])], -1)
            return state[:, None, :2] + offsets[..., None] * heading[:, None]

        gap = centres(state_i, layout.offsets[i])[:, :, None] - centres(state_j, layout.offsets[j])[:, None]
        distance = torch.sqrt((gap**2).sum(-1).flatten(1).min(-1).values + 1e-6)
        return torch.relu(1.0 - distance / (layout.radius[i] + layout.radius[j]))

    outputs = []
    for function in (reference, lambda a, b: layout.penalty(a, b, i, j, 0.0)):
        x = states[0, 0, i, t].clone().requires_grad_(True)
        value = function(x, states[0, 0, j, t])
        (grad,) = torch.autograd.grad(value.sum(), x)
        outputs.append((value.detach(), grad))
    (expected, expected_grad), (value, grad) = outputs
    assert (expected > 0).sum() > 50
    assert torch.allclose(value, expected, atol=1e-4)
    assert torch.allclose(grad, expected_grad, atol=1e-3)
