"""`SegmentSet`: polylines resampled to short segments and bucketed in a uniform grid, so many points are matched
to their nearest segments at once by vectorised numpy (docs/interdrive.md, 'Single-agent labels')."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from langtraj.polylines import arc_lengths, project_on_segments, resample

SEGMENT_SPACING_M = 1.0
"""Longest segment after resampling lane and edge polylines (m)."""

GRID_CELL_M = 3.0
"""Side of a grid cell of the segment index (m)."""


@dataclass(frozen=True, eq=False)
class SegmentSet:
    """Short segments of several polylines in a uniform grid, for radius queries by many points at once."""

    start: np.ndarray  # float64 [G, 2]
    end: np.ndarray  # float64 [G, 2]
    owner: np.ndarray  # int64 [G], index of the polyline the segment belongs to
    station: np.ndarray  # float64 [G], arc length of the segment start along its polyline
    heading: np.ndarray  # float64 [G]
    owner_first: np.ndarray  # int64 [P], first segment of each polyline
    owner_stop: np.ndarray  # int64 [P], one past its last segment
    origin: np.ndarray  # float64 [2]
    shape: tuple[int, int]
    sorted_keys: np.ndarray  # int64 [G], grid cell of each segment, sorted
    order: np.ndarray  # int64 [G], segment index of each sorted key

    @classmethod
    def build(cls, polylines: list[np.ndarray], spacing: float = SEGMENT_SPACING_M) -> SegmentSet:
        """Resample `polylines` and index their segments; an empty or degenerate polyline gets no segments."""
        starts, ends, owners, stations = [], [], [], []
        first = np.zeros(len(polylines), np.int64)
        stop = np.zeros(len(polylines), np.int64)
        count = 0
        for i, line in enumerate(polylines):
            pts = resample(line, spacing)
            first[i] = count
            if len(pts) >= 2:
                starts.append(pts[:-1])
                ends.append(pts[1:])
                owners.append(np.full(len(pts) - 1, i, np.int64))
                stations.append(arc_lengths(pts)[:-1])
                count += len(pts) - 1
            stop[i] = count
        if count == 0:
            empty = np.zeros((0, 2))
            return cls(empty, empty, np.zeros(0, np.int64), np.zeros(0), np.zeros(0), first, stop, np.zeros(2), (0, 0),
                       np.zeros(0, np.int64), np.zeros(0, np.int64))  # fmt: skip
        start, end = np.concatenate(starts), np.concatenate(ends)
        delta = end - start
        mid = 0.5 * (start + end)
        origin = mid.min(axis=0) - GRID_CELL_M
        cells = np.floor((mid - origin) / GRID_CELL_M).astype(np.int64)
        shape = (int(cells[:, 0].max()) + 2, int(cells[:, 1].max()) + 2)
        keys = cells[:, 0] * shape[1] + cells[:, 1]
        order = np.argsort(keys, kind="stable")
        return cls(
            start,
            end,
            np.concatenate(owners),
            np.concatenate(stations),
            np.arctan2(delta[:, 1], delta[:, 0]),
            first,
            stop,
            origin,
            shape,
            keys[order],
            order,
        )

    def __len__(self) -> int:
        return len(self.owner)

    def candidates(self, xy: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Pairs (query index, segment index) of every segment that may lie within `radius` of a query point."""
        if len(self) == 0 or len(xy) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        reach = math.ceil((radius + SEGMENT_SPACING_M / 2) / GRID_CELL_M)
        cells = np.floor((xy - self.origin) / GRID_CELL_M).astype(np.int64)
        offsets = np.arange(-reach, reach + 1)
        cx = (cells[:, 0:1] + offsets[None, :])[:, :, None]
        cy = (cells[:, 1:2] + offsets[None, :])[:, None, :]
        inside = (cx >= 0) & (cx < self.shape[0]) & (cy >= 0) & (cy < self.shape[1])
        keys = np.where(inside, cx * self.shape[1] + cy, -1).reshape(len(xy), -1)
        lo = np.searchsorted(self.sorted_keys, keys, "left").ravel()
        hi = np.searchsorted(self.sorted_keys, keys, "right").ravel()
        counts = hi - lo
        total = int(counts.sum())
        query = np.repeat(np.repeat(np.arange(len(xy)), keys.shape[1]), counts)
        within = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        return query, self.order[np.repeat(lo, counts) + within]

    def project(self, xy: np.ndarray, segments: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance, signed lateral offset (left of the segment positive) and station of each point on its segment."""
        found = project_on_segments(xy, self.start[segments], self.end[segments], self.station[segments])
        return found.distance, found.offset, found.station

    def segments_of(self, owner: int) -> np.ndarray:
        """Segment indices of polyline `owner`."""
        return np.arange(self.owner_first[owner], self.owner_stop[owner])


def _best_per_query(query: np.ndarray, cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each query with at least one pair, the position (into the pair arrays) of its cheapest pair."""
    if len(query) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    order = np.lexsort((cost, query))
    q_sorted = query[order]
    first = np.concatenate([[True], q_sorted[1:] != q_sorted[:-1]])
    return q_sorted[first], order[first]
