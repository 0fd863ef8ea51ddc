"""Signed distance from object boxes to the road edge (positive off the road), as WOSAC defines it.

Road-edge polylines keep the road on their left. For each bottom corner of a box, the nearest edge
segment is chosen by 3-D distance with heights stretched 3x (so an overpass edge does not capture a
point on the road below), and the 2-D distance to it is signed by the side the point lies on; past a
segment's ends the sign follows the convexity of the joint with the neighbouring segment. A box's
value is that of its most off-road corner.

The nearest segment is found exactly with a k-d tree over short pieces of the segments plus a
brute-force fallback, so the result equals a search over every segment at a fraction of the cost.

See docs/metrics.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

Z_STRETCH = 3.0
"""Weight of height differences when matching a point to its nearest edge segment."""

CYCLIC_TOLERANCE_M2 = 1.0
"""A polyline whose ends are closer than this (squared metres) is a closed loop."""

FAR = 1e10
_PIECE = 1.0  # longest piece (stretched metres) indexed by the k-d tree
_NEIGHBOURS = 24
_QUERY_CHUNK = 8192  # points per query batch: bounds the [points, neighbours, 3] temporaries


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


@dataclass(frozen=True)
class RoadEdges:
    """Road-edge segments with what the sign rule needs about their neighbours.

    `prior[k]` / `next[k]` is the index of the segment before / after segment k, or -1 at an open
    end; `convex_prior[k]` / `convex_next[k]` says whether the joint with it turns left.
    """

    start: np.ndarray  # float64 [K, 3]
    end: np.ndarray  # float64 [K, 3]
    prior: np.ndarray  # int64 [K]
    next: np.ndarray  # int64 [K]
    convex_prior: np.ndarray  # bool [K]
    convex_next: np.ndarray  # bool [K]

    @classmethod
    def from_polylines(cls, polylines: Sequence[np.ndarray]) -> RoadEdges:
        """Segments of every polyline with at least two points, in order.

        Closed loops wrap around at their ends only when they are the longest polylines of the map:
        WOSAC pads polylines to a common length before wrapping, so a shorter loop wraps onto
        padding and keeps the end segment's own side. This reproduces that behaviour.
        """
        kept = [np.asarray(p, np.float64) for p in polylines if len(p) >= 2]
        if not kept:
            empty = np.zeros((0, 3))
            none = np.zeros(0, np.int64)
            return cls(empty, empty, none, none, none.astype(bool), none.astype(bool))
        longest = max(len(p) for p in kept)
        starts, ends, prior, nxt, cprior, cnext = [], [], [], [], [], []
        offset = 0
        for points in kept:
            m = len(points) - 1
            s, e = points[:-1], points[1:]
            d = (e - s)[:, :2]
            idx = offset + np.arange(m)
            wraps = len(points) == longest and ((points[0] - points[-1]) ** 2).sum() < CYCLIC_TOLERANCE_M2
            p = idx - 1
            n = idx + 1
            p[0] = offset + m - 1 if wraps else -1
            n[-1] = offset if wraps else -1
            turn_prior = _cross(np.roll(d, 1, axis=0), d) > 0
            turn_next = _cross(d, np.roll(d, -1, axis=0)) > 0
            starts.append(s), ends.append(e), prior.append(p), nxt.append(n)
            cprior.append(turn_prior), cnext.append(turn_next)
            offset += m
        return cls(
            np.concatenate(starts),
            np.concatenate(ends),
            np.concatenate(prior),
            np.concatenate(nxt),
            np.concatenate(cprior),
            np.concatenate(cnext),
        )

    @property
    def num_segments(self) -> int:
        return len(self.start)


def _segment_geometry(points: np.ndarray, edges: RoadEdges, seg: np.ndarray):
    """Stretched 3-D distance, 2-D distance, side sign and projection parameter of points to segments."""
    s, e = edges.start[seg], edges.end[seg]
    to_point = points - s
    along = e - s
    denom = (along[..., :2] ** 2).sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(denom > 0, (to_point[..., :2] * along[..., :2]).sum(-1) / denom, 0.0)
    offset = to_point - along * np.clip(rel, 0.0, 1.0)[..., None]
    stretched = np.sqrt(offset[..., 0] ** 2 + offset[..., 1] ** 2 + (Z_STRETCH * offset[..., 2]) ** 2)
    planar = np.sqrt(offset[..., 0] ** 2 + offset[..., 1] ** 2)
    side = np.sign(_cross(to_point[..., :2], along[..., :2]))
    return stretched, planar, side, rel


class RoadEdgeIndex:
    """Nearest road-edge segment queries over one map."""

    def __init__(self, edges: RoadEdges):
        self.edges = edges
        lengths = np.sqrt((((edges.end - edges.start) * [1.0, 1.0, Z_STRETCH]) ** 2).sum(-1))
        pieces = np.maximum(np.ceil(lengths / _PIECE).astype(np.int64), 1)
        self._piece_parent = np.repeat(np.arange(edges.num_segments), pieces)
        first = np.repeat(np.cumsum(pieces) - pieces, pieces)
        frac = (np.arange(len(self._piece_parent)) - first + 0.5) / pieces[self._piece_parent]
        centre = edges.start[self._piece_parent] + (edges.end - edges.start)[self._piece_parent] * frac[:, None]
        self._radius = float((lengths / pieces).max() / 2) if len(lengths) else 0.0
        self._tree = cKDTree(centre * [1.0, 1.0, Z_STRETCH]) if len(centre) else None

    def nearest_segment(self, points: np.ndarray) -> np.ndarray:
        """Index of the nearest segment (stretched 3-D distance, lowest index on ties) for points [M, 3]."""
        k = min(_NEIGHBOURS, len(self._piece_parent))
        dist, piece = self._tree.query(points * [1.0, 1.0, Z_STRETCH], k=k)
        dist, piece = dist.reshape(len(points), k), piece.reshape(len(points), k)
        candidates = self._piece_parent[piece]  # [M, k]
        stretched = _segment_geometry(points[:, None, :], self.edges, candidates)[0]
        best = _argmin_lowest_index(stretched, candidates)
        # Exact when every piece that could hold a nearer point was among the k returned.
        bound = stretched[np.arange(len(points)), best] + self._radius
        unsure = (dist[:, -1] <= bound) & (k < len(self._piece_parent))
        chosen = candidates[np.arange(len(points)), best]
        for chunk in np.array_split(np.flatnonzero(unsure), max(1, int(unsure.sum()) // 256)):
            if len(chunk):
                all_seg = np.arange(self.edges.num_segments)[None, :]
                full = _segment_geometry(points[chunk, None, :], self.edges, all_seg)[0]
                chosen[chunk] = full.argmin(axis=1)
        return chosen

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Signed 2-D distance [M] from points [M, 3] to the road edge: negative on the road."""
        edges = self.edges
        seg = self.nearest_segment(points)
        _, planar, side, rel = _segment_geometry(points, edges, seg)
        sign = side
        for neighbour, convex, outside in (
            (edges.prior[seg], edges.convex_prior[seg], rel < 0.0),
            (edges.next[seg], edges.convex_next[seg], rel > 1.0),
        ):
            use = outside & (neighbour >= 0)
            if use.any():
                other = _segment_geometry(points[use], edges, neighbour[use])[2]
                own = side[use]
                sign = sign.copy()
                sign[use] = np.where(convex[use], np.maximum(own, other), np.minimum(own, other))
        return sign * planar


def road_edge_index(polylines: Sequence[np.ndarray]) -> RoadEdgeIndex | None:
    """The index of a scene's road-edge polylines, or None when they have no segment (nothing is off road)."""
    edges = RoadEdges.from_polylines(polylines)
    return RoadEdgeIndex(edges) if edges.num_segments else None


def _argmin_lowest_index(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Column of the minimum of each row, ties going to the lowest `index`."""
    low = values.min(axis=1, keepdims=True)
    masked = np.where(values == low, index, np.iinfo(np.int64).max)
    return masked.argmin(axis=1)


def box_bottom_corners(x, y, z, heading, length, width, height) -> np.ndarray:
    """The four bottom corners [..., 4, 3] of upright boxes, counter-clockwise from front-left."""
    c, s = np.cos(heading), np.sin(heading)
    signs = np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]], np.float64)
    lx = signs[:, 0] * (length[..., None] / 2)
    ly = signs[:, 1] * (width[..., None] / 2)
    cx = x[..., None] + c[..., None] * lx - s[..., None] * ly
    cy = y[..., None] + s[..., None] * lx + c[..., None] * ly
    cz = np.broadcast_to((z - height / 2)[..., None], cx.shape)
    return np.stack([cx, cy, cz], -1)


def distance_to_road_edge(index: RoadEdgeIndex, x, y, z, heading, length, width, height, valid) -> np.ndarray:
    """Signed distance of each box's most off-road corner, any shape [...]; -FAR where invalid."""
    corners = box_bottom_corners(x, y, z, heading, length, width, height)
    flat = corners.reshape(-1, 3)
    parts = [index.signed_distance(flat[i : i + _QUERY_CHUNK]) for i in range(0, len(flat), _QUERY_CHUNK)]
    dist = np.concatenate(parts).reshape(corners.shape[:-1]).max(axis=-1)
    return np.where(valid, dist, -FAR)
