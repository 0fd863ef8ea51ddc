"""Nearest points on line segments, differentiable in the query points, for the map costs.

The nearest segment is searched without autograd (a k-d tree over segment pieces where the points x
segments table is large); the distance to the chosen segment is then recomputed with autograd, so the
gradient is the exact one of the distance to the nearest segment.

See docs/simulation.md.
"""

from __future__ import annotations

import numpy as np
import torch
from scipy.spatial import cKDTree
from torch import Tensor

CHUNK_ELEMENTS = 1 << 22
"""Point-segment pairs per chunk of the nearest-segment search (bounds its temporary memory)."""


def closest_on_segments(points: Tensor, start: Tensor, end: Tensor) -> Tensor:
    """The point of segment (start[i], end[i]) closest to points[i]; all [..., 2], broadcasting."""
    direction = end - start
    length2 = (direction * direction).sum(-1).clamp(min=1e-12)
    along = (((points - start) * direction).sum(-1) / length2).clamp(0.0, 1.0)
    return start + along[..., None] * direction


PIECE = 2.0
"""Longest piece (m) a segment is cut into for the nearest-segment index; each piece is keyed by its centre."""
NEIGHBOURS = (8, 64)
"""Pieces the index offers a point, in rounds: a point left unsure by one round gets the next, then every segment."""


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

    Where the table is small every point meets every segment. Otherwise segments are cut into pieces of
    at most `PIECE` m, a k-d tree over the piece centres (scipy) offers each point its nearest pieces
    (`NEIGHBOURS` of them, in rounds), and a point for which a piece not offered could still hold a
    nearer segment (the farthest offered centre is within the best distance plus half a piece) goes to
    the next round, then to every segment; so the distance found is the nearest one (between segments
    at the same distance, e.g. at a shared vertex, either may be returned)."""
    flat = points.detach().reshape(-1, 2)
    with torch.no_grad():
        if flat.shape[0] * start.shape[0] <= CHUNK_ELEMENTS:
            return _brute_force(flat, start, end).reshape(points.shape[:-1])
        a, b = start.detach().double().cpu().numpy(), end.detach().double().cpu().numpy()
        lengths = np.linalg.norm(b - a, axis=-1)
        pieces = np.maximum(np.ceil(lengths / PIECE).astype(np.int64), 1)
        parent = np.repeat(np.arange(len(a)), pieces)
        first = np.repeat(np.cumsum(pieces) - pieces, pieces)
        frac = (np.arange(len(parent)) - first + 0.5) / pieces[parent]
        centres = a[parent] + (b - a)[parent] * frac[:, None]
        half_piece = float((lengths / pieces).max() / 2)
        query = flat.double().cpu().numpy()
        tree = cKDTree(centres)
        index = torch.empty(len(query), dtype=torch.long, device=flat.device)
        todo = np.arange(len(query))
        for k in NEIGHBOURS:  # more pieces for the points the fewer left unsure
            if not len(todo):
                break
            k = min(k, len(parent))
            reach, piece = tree.query(query[todo], k=k)
            reach, piece = reach.reshape(len(todo), k), piece.reshape(len(todo), k)
            candidates = parent[piece]  # [N, k]
            ca, cb = a[candidates], b[candidates]
            direction = cb - ca
            along = ((query[todo, None] - ca) * direction).sum(-1) / np.maximum((direction**2).sum(-1), 1e-12)
            closest = ca + np.clip(along, 0.0, 1.0)[..., None] * direction
            distance = np.linalg.norm(query[todo, None] - closest, axis=-1)
            best = distance.argmin(-1)
            rows = np.arange(len(todo))
            index[torch.as_tensor(todo, device=flat.device)] = torch.as_tensor(
                candidates[rows, best], device=flat.device
            )
            sure = (reach[:, -1] > distance[rows, best] + half_piece) | (k == len(parent))
            todo = todo[~sure]
        if len(todo):
            rows = torch.as_tensor(todo, device=flat.device)
            index[rows] = _brute_force(flat[rows], start, end)
        return index.reshape(points.shape[:-1])


def offset_to_segments(points: Tensor, start: Tensor, end: Tensor) -> tuple[Tensor, Tensor]:
    """For each of `points` [..., 2]: the vector [..., 2] from its nearest segment (among start, end
    [K, 2], K > 0) to it, differentiable in `points`, and that segment's index (long [...])."""
    index = nearest_segment(points, start, end)
    closest = closest_on_segments(points, start[index], end[index])
    return points - closest, index
