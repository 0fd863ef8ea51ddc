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


CELL = 20.0
"""Side (m) of the square cells the nearest-segment search groups points into."""
REACH = 20.0
"""A cell's points are first compared with the segments whose bounding box comes within this many metres
of the cell; a point whose nearest of those is farther is searched among all segments."""


def _brute_force(points: Tensor, start: Tensor, end: Tensor) -> Tensor:
    """Index of the nearest of all segments for points [N, 2], in chunks."""
    chunk = max(1, CHUNK_ELEMENTS // start.shape[0])
    found = []
    for piece in points.split(chunk):
        closest = closest_on_segments(piece[:, None], start[None], end[None])
        found.append(((piece[:, None] - closest) ** 2).sum(-1).argmin(-1))
    return torch.cat(found) if found else points.new_zeros(0, dtype=torch.long)


def nearest_segment(points: Tensor, start: Tensor, end: Tensor) -> Tensor:
    """Index (long [...]) of the segment nearest to each of `points` [..., 2] among start, end [K, 2], K > 0.

    Exact: points are grouped by `CELL`-metre cells and compared with the segments near their cell, which
    hold every segment within `REACH` m of them; the rare point farther from all of those is searched
    among every segment. Where the table is small, every point meets every segment at once."""
    flat = points.detach().reshape(-1, 2)
    with torch.no_grad():
        if flat.shape[0] * start.shape[0] <= CHUNK_ELEMENTS:
            return _brute_force(flat, start, end).reshape(points.shape[:-1])
        index = torch.empty(flat.shape[0], dtype=torch.long, device=flat.device)
        low, high = torch.minimum(start, end), torch.maximum(start, end)
        cells, group = torch.unique(torch.floor(flat / CELL).long(), dim=0, return_inverse=True)
        order = torch.argsort(group)
        bounds = torch.searchsorted(group[order], torch.arange(len(cells) + 1, device=flat.device))
        for c, cell in enumerate(cells.to(flat.dtype)):
            rows = order[bounds[c] : bounds[c + 1]]
            lo, hi = cell * CELL - REACH, (cell + 1) * CELL + REACH
            near = ((high >= lo) & (low <= hi)).all(-1).nonzero()[:, 0]
            if len(near) == 0:
                index[rows] = _brute_force(flat[rows], start, end)
                continue
            pts = flat[rows]
            closest = closest_on_segments(pts[:, None], start[near][None], end[near][None])
            distance2 = ((pts[:, None] - closest) ** 2).sum(-1)
            best, arg = distance2.min(-1)
            index[rows] = near[arg]
            far = best > REACH**2
            if far.any():
                index[rows[far]] = _brute_force(pts[far], start, end)
        return index.reshape(points.shape[:-1])


def offset_to_segments(points: Tensor, start: Tensor, end: Tensor) -> tuple[Tensor, Tensor]:
    """For each of `points` [..., 2]: the vector [..., 2] from its nearest segment (among start, end
    [K, 2], K > 0) to it, differentiable in `points`, and that segment's index (long [...])."""
    index = nearest_segment(points, start, end)
    closest = closest_on_segments(points, start[index], end[index])
    return points - closest, index
