"""Nearest points on line segments, differentiable in the query points, for the map and route costs (the torch
counterpart of `langtraj.polylines`).

The nearest segment is searched without autograd (an STR-tree over the segments where the points x
segments table is large); the distance to the chosen segment is then recomputed with autograd, so the
gradient is the exact one of the distance to the nearest segment.

See docs/simulation.md.
"""

from __future__ import annotations

import shapely
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

    Where the table is small every point meets every segment; otherwise an STR-tree over the segments
    (shapely's, GEOS) finds each point's nearest one exactly. Between segments at the same distance (at a
    shared vertex, say) either may be returned."""
    flat = points.detach().reshape(-1, 2)
    with torch.no_grad():
        if flat.shape[0] * start.shape[0] <= CHUNK_ELEMENTS:
            return _brute_force(flat, start, end).reshape(points.shape[:-1])
        segments = torch.stack([start, end], dim=1).detach().double().cpu().numpy()
        tree = shapely.STRtree(shapely.linestrings(segments))
        found, nearest = tree.query_nearest(shapely.points(flat.double().cpu().numpy()), all_matches=False)
        index = torch.full((flat.shape[0],), -1, dtype=torch.long)
        index[torch.as_tensor(found)] = torch.as_tensor(nearest, dtype=torch.long)
        missing = (index < 0).nonzero()[:, 0]  # points GEOS cannot place (not finite)
        if len(missing):
            index[missing] = _brute_force(flat[missing].cpu(), start.cpu(), end.cpu())
        return index.to(points.device).reshape(points.shape[:-1])


def offset_to_segments(points: Tensor, start: Tensor, end: Tensor) -> tuple[Tensor, Tensor]:
    """For each of `points` [..., 2]: the vector [..., 2] from its nearest segment (among start, end
    [K, 2], K > 0) to it, differentiable in `points`, and that segment's index (long [...])."""
    index = nearest_segment(points, start, end)
    closest = closest_on_segments(points, start[index], end[index])
    return points - closest, index


def offset_and_station(points: Tensor, start: Tensor, end: Tensor, arc: Tensor) -> tuple[Tensor, Tensor]:
    """For each of `points` [..., 2]: the vector [..., 2] from its nearest segment (among start, end [K, 2] of one
    polyline, K > 0) to it, and its station [...]: `arc[k]` (the station of segment k's start, [K]) plus its
    projection on the line of that segment, not clamped (beyond the polyline's ends it keeps counting);
    differentiable in `points`."""
    offset, index = offset_to_segments(points, start, end)
    direction = end[index] - start[index]
    along = ((points - start[index]) * direction).sum(-1) / direction.norm(dim=-1).clamp(min=1e-9)
    return offset, arc[index] + along
