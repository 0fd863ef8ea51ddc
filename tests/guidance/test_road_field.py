"""The road field (signed road-edge distance on a grid) against the exact nearest-segment search it
replaces in simulations: values and gradients, on constructed roads."""

from __future__ import annotations

import math

import pytest
import torch

from langtraj.errors import InputError
from langtraj.guidance import OnRoadCost
from langtraj.guidance.costs import signed_edge_distance
from langtraj.guidance.road_field import RoadField

from .helpers import make_scene

# A straight road along x between y = -2 (edge running east) and y = 6 (edge running west).
STRAIGHT = [[[-50.0, -2.0], [50.0, -2.0]], [[50.0, 6.0], [-50.0, 6.0]]]


def _ring(radius: float, pieces: int, clockwise: bool) -> list[list[list[float]]]:
    """A circle of `pieces` segments (about 0.5 m each for WOMD-like edges): counter-clockwise keeps the
    inside on its left (the road inside), clockwise the outside."""
    angles = [2 * math.pi * i / pieces for i in range(pieces + 1)]
    if clockwise:
        angles = angles[::-1]
    points = [[radius * math.cos(a), radius * math.sin(a)] for a in angles]
    return [[points[i], points[i + 1]] for i in range(pieces)]


# A ring road between radii 20 and 28: inner edge clockwise (road outside it), outer counter-clockwise.
RING = _ring(20.0, 250, clockwise=True) + _ring(28.0, 350, clockwise=False)


def _exact_and_field(edges, points: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """Exact and field signed distances at `points` [P, 2], with their gradients, and the inside mask."""
    segments = torch.tensor(edges, dtype=torch.float32)
    field = RoadField.build(segments[:, 0], segments[:, 1])
    exact_points = points.clone().requires_grad_(True)
    exact = signed_edge_distance(exact_points, segments)
    (exact_grad,) = torch.autograd.grad(exact.sum(), exact_points)
    field_points = points.clone().requires_grad_(True)
    value, inside = field.sample(field_points)
    (field_grad,) = torch.autograd.grad(value.sum(), field_points)
    return exact.detach(), exact_grad, value.detach(), field_grad, inside


def test_on_a_straight_road_the_field_is_the_exact_signed_distance_and_gradient():
    g = torch.Generator().manual_seed(0)
    points = torch.rand(5000, 2, generator=g) * torch.tensor([80.0, 30.0]) - torch.tensor([40.0, 13.0])
    exact, exact_grad, value, grad, inside = _exact_and_field(STRAIGHT, points)
    assert inside.all()
    # Between the edges the distance to the nearer one is linear except on the mid-line (y = 2), where
    # the nearest edge changes; away from it the interpolation is exact.
    away = (points[:, 1] - 2.0).abs() > 0.75
    assert torch.allclose(value[away], exact[away], atol=1e-3)
    # (The exact gradient is d / sqrt(d^2 + 1e-6), below 1 within millimetres of an edge: not compared.)
    clear = away & (exact.abs() > 0.05)
    assert torch.allclose(grad[clear], exact_grad[clear], atol=1e-3)
    assert (value[points[:, 1] < -2.0] > 0).all() and (value[(points[:, 1] > -1.9) & (points[:, 1] < 5.9)] < 0).all()


def test_on_a_curved_road_of_short_segments_values_and_gradients_agree_within_centimetres():
    g = torch.Generator().manual_seed(1)
    radius = 14.0 + torch.rand(20000, generator=g) * 20.0
    angle = torch.rand(20000, generator=g) * 2 * math.pi
    points = torch.stack([radius * torch.cos(angle), radius * torch.sin(angle)], -1)
    exact, exact_grad, value, grad, inside = _exact_and_field(RING, points)
    assert inside.all()
    away = (radius - 24.0).abs() > 0.75  # not on the mid-line, where the nearest edge changes
    close = exact.abs() < 3.5  # every surrounding node within 4 m of an edge: exact node values
    error = (value - exact).abs()
    assert error[away & close].quantile(0.99) < 0.05 and error[away & close].max() < 0.3
    assert error[away & ~close].max() < 0.5  # farther: the segment the distance transform finds
    cosine = (grad * exact_grad).sum(-1) / (grad.norm(dim=-1) * exact_grad.norm(dim=-1))
    assert (cosine[away] > 0.99).float().mean() > 0.98
    # Off the road (beyond either edge) it is positive, on it negative, as the exact distance.
    off = (radius < 19.8) | (radius > 28.2)
    on = (radius > 20.2) & (radius < 27.8)
    assert (value[off] > 0).all() and (value[on] < 0).all()


def test_the_on_road_cost_with_the_field_matches_the_exact_cost_and_searches_points_outside_it():
    scene = make_scene(3, road_edges=RING)
    with_field = scene.with_road_field()
    g = torch.Generator().manual_seed(2)
    radius = 18.0 + torch.rand(2, 3, 40, generator=g) * 12.0
    angle = torch.rand(2, 3, 40, generator=g) * 2 * math.pi
    states = torch.stack([radius * torch.cos(angle), radius * torch.sin(angle), angle, radius * 0], -1)
    states[1, 2, :5, :2] = 500.0  # far outside the field: searched exactly
    outputs = []
    for s in (scene, with_field):
        x = states.clone().requires_grad_(True)
        value = OnRoadCost().per_agent(x, s)
        (grad,) = torch.autograd.grad(value.sum(), x)
        outputs.append((value.detach(), grad))
    (exact, exact_grad), (value, grad) = outputs
    assert torch.allclose(value, exact, rtol=0.02, atol=1e-3)
    assert torch.allclose(grad, exact_grad, atol=0.02)
    assert torch.equal(grad[1, 2, :5], exact_grad[1, 2, :5])  # the far points: the exact search's gradient


def test_the_field_covers_the_given_points_and_refuses_bad_segments():
    segments = torch.tensor(STRAIGHT)
    plain = RoadField.build(segments[:, 0], segments[:, 1])
    far = torch.tensor([[90.0, 0.0]])  # 40 m past the road's end, outside the grid's 30 m margin
    assert not plain.sample(far)[1].item()
    covering = RoadField.build(segments[:, 0], segments[:, 1], cover=far)
    value, inside = covering.sample(far)
    assert inside.item() and value.item() == pytest.approx(signed_edge_distance(far, segments).item(), abs=0.5)
    farther = RoadField.build(segments[:, 0], segments[:, 1], cover=torch.tensor([[300.0, 0.0]]))
    assert not farther.sample(torch.tensor([[300.0, 0.0]]))[1].item()  # 250 m from every edge: no value
    coarse = RoadField.build(segments[:, 0], segments[:, 1], cover=far, max_nodes=10_000)
    assert coarse.shape[0] * coarse.shape[1] <= 10_000 and coarse.resolution > 0.5
    with pytest.raises(InputError, match="non-empty"):
        RoadField.build(torch.zeros(0, 2), torch.zeros(0, 2))
    with pytest.raises(InputError, match="finite"):
        RoadField.build(torch.tensor([[0.0, math.nan]]), torch.tensor([[1.0, 0.0]]))
    assert make_scene(2).with_road_field().road_field is None  # no road edges: nothing to build
