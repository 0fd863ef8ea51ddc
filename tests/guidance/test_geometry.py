"""The nearest-segment search: the k-d tree search finds the distance comparing every pair finds."""

import torch

from langtraj.guidance import geometry


def test_tree_search_matches_every_pair_including_points_far_from_every_segment():
    g = torch.Generator().manual_seed(0)
    start = torch.rand(3000, 2, generator=g) * 300.0
    end = start + torch.randn(3000, 2, generator=g) * 3.0
    points = torch.cat([torch.rand(1500, 2, generator=g) * 300.0, torch.rand(50, 2, generator=g) * 200.0 + 400.0])
    assert points.shape[0] * start.shape[0] > geometry.CHUNK_ELEMENTS  # the tree path
    found = geometry.nearest_segment(points[:, None], start, end)[:, 0]
    expected = geometry._brute_force(points, start, end)

    def distance(index):
        closest = geometry.closest_on_segments(points, start[index], end[index])
        return (points - closest).norm(dim=-1)

    assert torch.allclose(distance(found), distance(expected), atol=1e-4)
    assert (found == expected).float().mean() > 0.99  # the same segment but at ties
