"""Nearest points on line segments, differentiable in the query points, for the map costs.

The nearest segment is searched without autograd in chunks (a points x segments table can be large);
the distance to the chosen segment is then recomputed with autograd, so the gradient is the exact one
of the distance to the nearest segment.

See docs/simulation.md.
"""

from __future__ import annotations

import torch
from torch import Tensor

CHUNK_ELEMENTS = 1 << 22
"""Point-segment pairs per chunk of the nearest-segment search (bounds its temporary memory)."""


def closest_on_segments(points: Tensor, start: Tensor, end: Tensor) -> Tensor:
    """The point of segment (start[i], end[i]) closest to points[i]; all [..., 2], broadcasting."""
    direction = end - start
    length2 = (direction * direction).sum(-1).clamp(min=1e-12)
    along = (((points - start) * direction).sum(-1) / length2).clamp(0.0, 1.0)
    return start + along[..., None] * direction


def nearest_segment(points: Tensor, start: Tensor, end: Tensor) -> Tensor:
    """Index (long [...]) of the segment nearest to each of `points` [..., 2] among start, end [K, 2], K > 0."""
    flat = points.detach().reshape(-1, 2)
    chunk = max(1, CHUNK_ELEMENTS // start.shape[0])
    found = []
    with torch.no_grad():
        for piece in flat.split(chunk):
            closest = closest_on_segments(piece[:, None], start[None], end[None])
            found.append(((piece[:, None] - closest) ** 2).sum(-1).argmin(-1))
    index = torch.cat(found) if found else flat.new_zeros(0, dtype=torch.long)
    return index.reshape(points.shape[:-1])


def offset_to_segments(points: Tensor, start: Tensor, end: Tensor) -> tuple[Tensor, Tensor]:
    """For each of `points` [..., 2]: the vector [..., 2] from its nearest segment (among start, end
    [K, 2], K > 0) to it, differentiable in `points`, and that segment's index (long [...])."""
    index = nearest_segment(points, start, end)
    closest = closest_on_segments(points, start[index], end[index])
    return points - closest, index
