"""The hard-constraint projection keeps constructed paths on a constructed road and apart from a neighbour."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
import torch

from langtraj.errors import InputError
from langtraj.guidance.costs import signed_road_distance
from langtraj.guidance.disks import DiskLayout
from langtraj.guidance.projection import (
    HardConstraints,
    ProjectionAgents,
    braking_delay,
    corner_reach,
    current_overlaps,
    polish_on_road,
    project_on_road,
    project_states,
    projection_hook,
)
from langtraj.model.diffusion import timestep_sequence
from langtraj.model.dynamics import Unicycle

from .helpers import make_scene

# A straight road along x from y = -2 to y = 6 (edges keep the road on their left).
ROAD = [[[-200.0, -2.0], [200.0, -2.0]], [[200.0, 6.0], [-200.0, 6.0]]]
CONFIG = HardConstraints(iterations=4)


def agents(num: int, *, road=None, movable=None, exempt=None) -> ProjectionAgents:
    return ProjectionAgents(
        road=torch.ones(num, dtype=torch.bool) if road is None else torch.tensor(road),
        movable=torch.ones(num, dtype=torch.bool) if movable is None else torch.tensor(movable),
        exempt=torch.zeros(num, num, dtype=torch.bool) if exempt is None else exempt,
    )


def drifting(steps: int = 40, speed: float = 10.0, drift: float = -0.15) -> torch.Tensor:
    """One car at y = 0 heading east, its path drifting `drift` m per step towards the lower edge."""
    t = torch.arange(1, steps + 1, dtype=torch.float32)
    x, y = speed * 0.1 * t, drift * t
    heading = torch.full_like(t, math.atan2(drift, speed * 0.1))
    return torch.stack([x, y, heading, torch.full_like(t, speed)], -1)[None, None]


def start(states: torch.Tensor) -> torch.Tensor:
    """The state one step before each path's first (constant velocity backwards), as a planner's current state."""
    return 2 * states[:, :, 0] - states[:, :, 1]


def min_disk_distance(states: torch.Tensor, scene, i: int, j: int) -> float:
    layout = DiskLayout.of(scene, 5, states)
    a, b = states[0, i], states[0, j]
    index_i = torch.full((a.shape[0],), i)
    index_j = torch.full((a.shape[0],), j)
    return float(layout.penalty(a, b, index_i, index_j, 0.0).max().detach())


def test_a_drifting_car_is_put_back_inside_the_edge_by_its_box_and_the_margin():
    scene = make_scene(1, road_edges=ROAD)
    states = drifting()
    assert float(signed_road_distance(states[..., :2], scene).max()) > 3  # leaves the road by 4 m
    projected, moved = project_states(start(states), states, scene, agents(1), CONFIG)
    assert moved.tolist() == [[True]]
    signed = signed_road_distance(projected[..., :2], scene)
    heading = states[..., 2]  # the box's reach towards the edge (normal -y) at its heading
    reach = 2.25 * torch.sin(heading).abs() + 1.0 * torch.cos(heading).abs()
    assert float((signed + reach).max()) <= -CONFIG.road_margin + 1e-4
    assert float(reach.min()) > 1.3  # more than half the width: the corners, not the sides, come nearest
    # Points already well inside stay where they were; x is untouched (the edge runs along x).
    inside = signed_road_distance(states[..., :2], scene) < -1.6
    assert torch.allclose(projected[..., :2][inside], states[..., :2][inside])
    assert torch.allclose(projected[..., 0], states[..., 0])


def test_agents_not_kept_on_the_road_and_maps_without_edges_are_left_alone():
    scene = make_scene(2, road_edges=ROAD)
    second = drifting(drift=-0.15)
    second[..., 0] += 60.0  # far from the first
    states = torch.cat([drifting(drift=-0.5), second], dim=1)
    projected, moved = project_states(start(states), states, scene, agents(2, road=[True, False]), CONFIG)
    assert moved.tolist() == [[True, False]]
    assert torch.allclose(projected[:, 1, :, :2], states[:, 1, :, :2])  # not a road agent
    no_edges = make_scene(2)
    assert project_states(start(states), states, no_edges, agents(2), CONFIG)[1].sum() == 0  # nothing to keep to


def test_two_cars_driving_into_each_other_end_apart_and_a_fixed_one_is_not_moved():
    scene = make_scene(2, road_edges=ROAD)
    t = torch.arange(1, 31, dtype=torch.float32)
    ahead = torch.stack([10 + 0.5 * t, torch.full_like(t, 2.0), torch.zeros_like(t), torch.full_like(t, 5.0)], -1)
    behind = torch.stack([0.0 + 1.0 * t, torch.full_like(t, 2.0), torch.zeros_like(t), torch.full_like(t, 10.0)], -1)
    states = torch.stack([ahead, behind])[None]  # the follower reaches the leader at step 11 and drives through it
    assert min_disk_distance(states, scene, 0, 1) > 0.5
    for movable in ([True, True], [False, True]):
        projected, moved = project_states(start(states), states, scene, agents(2, movable=movable), CONFIG)
        full = torch.cat([projected, states[..., 3:]], dim=-1)
        assert min_disk_distance(full, scene, 0, 1) < 0.05  # at most 5 % of the reach left overlapping
        assert moved[0, 1]
        if not movable[0]:
            assert not moved[0, 0] and torch.equal(projected[0, 0, :, :2], states[0, 0, :, :2])
        # The follower is held back along the lane, not swerved across it.
        assert float((projected[0, 1, :, 1] - 2.0).abs().max()) < 0.2


def test_pairs_overlapping_at_the_start_and_exempt_pairs_are_not_pushed():
    scene = make_scene(2, road_edges=ROAD)
    side_by_side = torch.tensor([[0.0, 1.5, 0.0, 0.0], [0.0, 3.0, 0.0, 0.0]])  # overlapping across the lane
    states = side_by_side[None, :, None].expand(1, 2, 10, 4).clone()
    exempt = current_overlaps(states[:, :, 0], scene, CONFIG)
    assert exempt.shape == (1, 2, 2) and exempt[0, 0, 1] and exempt[0, 1, 0]
    _, moved = project_states(start(states), states, scene, agents(2, exempt=exempt), CONFIG)
    assert not moved.any()
    _, moved = project_states(start(states), states, scene, agents(2), CONFIG)
    assert moved.any()  # not exempt: pushed apart


def test_the_hook_refits_only_the_paths_it_moved_through_the_unicycle_and_keeps_them_on_the_road():
    dynamics = Unicycle()
    scene = make_scene(2, road_edges=ROAD)
    initial = torch.tensor([[[0.0, 0.0, 0.0, 10.0], [0.0, 4.0, 0.0, 10.0]]])  # [1, 2, 4]
    actions = torch.zeros(1, 2, 8, 2)
    actions[0, 0, :, 1] = -0.08  # the first car turns right, off the road; the second drives straight on
    rollout = lambda x: dynamics(initial, x)  # noqa: E731
    invert = lambda s, rows: dynamics.inverse(initial[rows], s, torch.ones(s.shape[:-1], dtype=torch.bool))[0]  # noqa: E731
    before = rollout(actions)
    assert float(signed_road_distance(before[0, 0, :, :2], scene).max()) > 0.5
    hook = projection_hook(CONFIG, scene, agents(2), initial, rollout, invert, num_steps=100, sampler_steps=5)
    last = timestep_sequence(100, num_inference_steps=5)[-1]
    out = hook(actions, torch.tensor([last]), actions)  # the last denoising step
    assert torch.equal(out[0, 1], actions[0, 1])  # unmoved: its actions kept exactly
    after = rollout(out)
    assert float(signed_road_distance(after[0, 0, :, :2], scene).max()) < -0.8  # within the refit's error
    assert torch.equal(hook(actions, torch.tensor([99]), actions), actions)  # not at an early step


def test_corner_reach_is_how_far_the_most_off_road_corner_lies_past_the_edge():
    scene = make_scene(1, road_edges=ROAD)  # the helper's agents are 4.5 m by 2 m
    states = torch.tensor([[[[0.0, -1.0, 0.0, 5.0], [0.0, -1.0, math.pi / 2, 5.0], [0.0, 3.0, 0.0, 5.0]]]])
    reach = corner_reach(states, scene, torch.tensor([0]))
    assert torch.allclose(reach[0, 0], torch.tensor([0.0, 1.25, -2.0]), atol=2e-3)  # side on the edge; nose past


def test_the_polish_drives_a_box_the_unicycle_left_past_the_edge_back_inside_and_touches_nothing_else():
    dynamics = Unicycle()
    scene = make_scene(3, road_edges=ROAD)
    initial = torch.tensor([[[0.0, 0.0, 0.0, 10.0], [0.0, 4.0, 0.0, 10.0], [0.0, 0.0, 0.0, 10.0]]])
    actions = torch.zeros(1, 3, 8, 2)
    actions[0, 0, :, 1] = actions[0, 2, :, 1] = -0.08  # the first and third cars turn off the road; the second not
    rollout = lambda x: dynamics(initial, x)  # noqa: E731
    rows = torch.tensor([0])
    assert float(corner_reach(rollout(actions), scene, rows).max()) > 2.0
    config = HardConstraints(polish=30)
    polished = polish_on_road(config, scene, agents(3, road=[True, True, False]), initial, rollout, actions)
    judged = corner_reach(rollout(polished), scene, rows)[..., : config.polish_steps]  # the steps it judges
    assert float(judged.max()) < -config.road_margin + 0.05
    assert torch.equal(polished[0, 1:], actions[0, 1:])  # inside already, and not kept on the road: untouched
    assert torch.equal(polish_on_road(HardConstraints(polish=0), scene, agents(3), initial, rollout, actions), actions)


def test_a_steer_only_path_is_steered_back_inside_at_the_speeds_it_planned():
    """A prompted agent's polish moves its yaw rate only: its accelerations (a prompt's "slows down", a turn's
    braking) are kept exactly, while a free agent on the same path may brake as well."""
    dynamics = Unicycle()
    scene = make_scene(2, road_edges=ROAD)
    initial = torch.tensor([[[0.0, 0.0, 0.0, 10.0], [0.0, 0.0, 0.0, 10.0]]])
    actions = torch.zeros(1, 2, 8, 2)
    actions[0, :, :, 0], actions[0, :, :, 1] = 0.5, -0.08  # both speed up while turning off the road
    rollout = lambda x: dynamics(initial, x)  # noqa: E731
    config = HardConstraints(polish=30)
    steered = replace(agents(2), steer_only=torch.tensor([True, False]))
    polished = polish_on_road(config, scene, steered, initial, rollout, actions)
    assert torch.equal(polished[0, 0, :, 0], actions[0, 0, :, 0])  # its accelerations untouched
    assert not torch.equal(polished[0, 1, :, 0], actions[0, 1, :, 0])  # the free one's not
    rows = torch.tensor([0])
    assert float(corner_reach(rollout(actions), scene, rows).max()) > 2.0
    judged = corner_reach(rollout(polished), scene, rows)[..., : config.polish_steps]
    assert float(judged.max()) < 0.0  # steered back inside the edge


def test_the_polish_judges_the_plans_first_seconds_only():
    """A car that turns off the road late in its plan (past `polish_steps`) keeps its actions exactly: the replans to
    come will see that corner; judged over the whole plan, its speed is polished away now."""
    dynamics = Unicycle()
    scene = make_scene(1, road_edges=ROAD)
    initial = torch.tensor([[[0.0, 0.0, 0.0, 10.0]]])
    actions = torch.zeros(1, 1, 16, 2)
    actions[0, 0, 10:, 1] = -0.3  # straight on for 5 s, then off the road
    rollout = lambda x: dynamics(initial, x)  # noqa: E731
    reach = corner_reach(rollout(actions), scene, torch.tensor([0]))[0, 0]
    assert float(reach[:30].max()) < -0.2 and float(reach.max()) > 1.0
    late = polish_on_road(HardConstraints(polish=10, polish_steps=30), scene, agents(1), initial, rollout, actions)
    assert torch.equal(late, actions)
    whole = polish_on_road(HardConstraints(polish=10, polish_steps=None), scene, agents(1), initial, rollout, actions)
    assert float(whole[0, 0, :10, 0].min()) < -0.1  # braking from the first action for a corner 5 s away


def test_the_polish_never_leaves_a_path_worse_than_it_found_it():
    """A rate far too large overshoots at every step: each path keeps the best actions it reached, here its own."""
    dynamics = Unicycle()
    scene = make_scene(1, road_edges=ROAD)
    initial = torch.tensor([[[0.0, -0.9, 0.0, 10.0]]])  # its side 0.1 m inside the edge, 0.1 m past the margin
    actions = torch.zeros(1, 1, 8, 2)
    rollout = lambda x: dynamics(initial, x)  # noqa: E731
    rows = torch.tensor([0])
    before = float(corner_reach(rollout(actions), scene, rows).max())
    polished = polish_on_road(HardConstraints(polish=5, polish_rate=4.0), scene, agents(1), initial, rollout, actions)
    assert float(corner_reach(rollout(polished), scene, rows).max()) <= before + 1e-6


def test_a_car_over_the_kerb_is_not_driven_off_it_but_kept_from_going_farther_and_a_standing_one_is_left():
    dynamics = Unicycle()
    scene = make_scene(1, road_edges=ROAD)
    initial = torch.tensor([[[0.0, -1.5, 0.0, 2.0]]])  # its side 0.5 m past the edge, rolling along it
    rollout = lambda x: dynamics(initial, x)  # noqa: E731
    along = torch.zeros(1, 1, 8, 2)
    assert torch.equal(polish_on_road(HardConstraints(), scene, agents(1), initial, rollout, along), along)
    turning_off = torch.zeros(1, 1, 8, 2)
    turning_off[0, 0, :, 0], turning_off[0, 0, :, 1] = 0.25, -0.1  # faster, turning further off the road
    reach = float(corner_reach(rollout(turning_off), scene, torch.tensor([0])).max())
    polished = polish_on_road(HardConstraints(polish=30), scene, agents(1), initial, rollout, turning_off)
    after = float(corner_reach(rollout(polished), scene, torch.tensor([0])).max())
    assert reach > 3.0 and after < 0.5 + 0.3  # brought back near where it was (its line)
    standing = initial.clone()
    standing[..., 3] = 0.0  # a standing car's plan is left as it is (it would be set driving)
    stand = lambda x: dynamics(standing, x)  # noqa: E731
    assert torch.equal(polish_on_road(HardConstraints(), scene, agents(1), standing, stand, turning_off), turning_off)


def test_bad_settings_are_refused():
    with pytest.raises(InputError, match="steps"):
        HardConstraints(steps=0)
    with pytest.raises(InputError, match="polish"):
        HardConstraints(polish=-1)
    with pytest.raises(InputError, match="polish_rate"):
        HardConstraints(polish_rate=float("inf"))
    with pytest.raises(InputError, match="road_margin"):
        HardConstraints(road_margin=float("nan"))


def test_a_delay_is_braked_into_from_the_start_not_taken_at_once():
    delay = torch.zeros(1, 1, 40)
    delay[0, 0, 19] = 4.0  # 4 m behind by step 20 (2 s)
    profile = braking_delay(delay)[0, 0]
    assert profile[19] == pytest.approx(4.0) and torch.all(profile[19:] == 4.0)  # met, and kept
    assert profile[9] == pytest.approx(1.0)  # (10 / 20)^2 of it after 1 s: a constant 2 m/s^2 of extra braking
    assert torch.all(profile[1:] >= profile[:-1])


def test_a_path_far_off_the_road_keeps_the_correction_of_its_last_point_near_it():
    scene = make_scene(1, road_edges=ROAD)
    states = drifting(drift=-0.3)  # leaves the road, then runs on to 12 m beyond it
    xy = project_on_road(states, scene, torch.ones(1, dtype=torch.bool), CONFIG)
    signed = signed_road_distance(states[..., :2], scene)[0, 0]
    first_far = int(torch.nonzero(signed > CONFIG.max_offroad)[0])
    shift = xy - states[..., :2]
    assert torch.allclose(shift[0, 0, first_far:], shift[0, 0, first_far - 1].expand_as(shift[0, 0, first_far:]))
    assert float(shift[0, 0, first_far - 1].norm()) > 1.0  # that point was pulled in, and the rest moves with it
    step = torch.linalg.vector_norm(xy[0, 0, 1:] - xy[0, 0, :-1], dim=-1)
    assert float(step.max()) < 1.5  # no jump in the projected path (1.04 m per step before)


def test_a_pull_over_may_bring_its_box_to_the_edge_the_others_keep_a_margin_from():
    scene = make_scene(2, road_edges=ROAD)
    # Two cars heading east, their right sides 0.1 m inside the lower edge (y = -2): inside, but within the margin.
    states = torch.stack([drifting(drift=0.0)[0, 0], drifting(drift=0.0)[0, 0]])[None].clone()
    states[..., 1] = torch.tensor([-0.9, -0.9])[None, :, None]
    states[0, 1, :, 0] += 50.0  # apart
    margin = torch.tensor([CONFIG.road_margin, 0.0])
    mover = ProjectionAgents(road=torch.ones(2, dtype=torch.bool), movable=torch.ones(2, dtype=torch.bool),
                             exempt=torch.zeros(2, 2, dtype=torch.bool), margin=margin)  # fmt: skip
    projected, moved = project_states(start(states), states, scene, mover, CONFIG)
    assert moved.tolist() == [[True, False]]  # the second (a pull-over at the kerb) stays where it is
    assert float(projected[0, 0, :, 1].min()) == pytest.approx(-2.0 + CONFIG.road_margin + 1.0, abs=1e-3)
