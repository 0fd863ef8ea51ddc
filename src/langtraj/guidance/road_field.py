"""The signed distance to the road edge on a grid, built once per simulation, for the on-road cost.

A guided simulation asks for the signed road-edge distance of every candidate agent state at every
denoising step of every replan: hundreds of thousands of points each time, on a map that never
changes. Searching the nearest segment for each took most of a guided simulation's time
(docs/benchmarks.md, 'Guided simulation'). The field stores the signed distance at the nodes of a
regular grid over the map, computed exactly as `OnRoadCost` defines it (distance to the nearest
road-edge segment, negative on its left); a point's value is the bilinear interpolation of its four
surrounding nodes, differentiable in the point. Where the nearest edge is a straight line the signed
distance is linear and the interpolation is exact; near an edge's vertices it is within a few
centimetres at the default spacing (`tests/guidance/test_road_field.py` measures both). Points
outside the grid are not interpolated: the caller computes them exactly.

Within a few metres of an edge, where the cost is decided, node values are exact distances to candidate
segments: those of the points sampled densely along the segments that lie nearest to the node (scipy's
k-d tree) and their neighbours along their polylines. Farther out they are the exact distance to the
segment of the nearest rasterized sample (scipy's Euclidean distance transform), which is the nearest
segment or within about a grid spacing of it; beyond 60 m from every edge the field holds nothing, and the
rare point there is searched exactly like a point outside the grid.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import torch
from scipy import ndimage
from scipy.spatial import cKDTree
from torch import Tensor

from langtraj.errors import InputError
from langtraj.polylines import project_on_segments

RESOLUTION = 0.5
"""Grid spacing in metres."""
MARGIN = 30.0
"""Metres of grid around the segments' bounding box; points farther out are left to the exact search."""
MAX_NODES = 4_000_000
"""Largest grid (nodes, 16 MB of float32); a larger map gets a coarser spacing."""
_SAMPLE = 0.1  # metres between the samples along each segment that the k-d tree indexes
_NEAREST = 2  # nearest samples whose segments (and their polyline neighbours) a node within _BAND compares
_BAND = 4.0  # metres from an edge within which node values are exact
_FAR = 60.0  # metres from every edge beyond which nodes hold no value (points there are searched exactly)
_CHUNK = 1 << 18  # nodes per chunk of the exact refinement


@dataclass(frozen=True, eq=False)
class RoadField:
    """Signed road-edge distance (m; positive off the road, i.e. on an edge's right) at the `shape` = (H, W)
    nodes `origin + (ix, iy) * resolution`, stored per grid cell so that a point reads its cell in one
    gather: `cells[iy * (W - 1) + ix]` holds the values at the cell's four corners (ix, iy), (ix + 1,
    iy), (ix, iy + 1), (ix + 1, iy + 1), and `valued` whether all four have one (nodes farther than
    `_FAR` m from every edge have none)."""

    origin: Tensor  # float64 [2]: x, y of node (0, 0)
    resolution: float
    shape: tuple[int, int]  # (H, W): nodes along y and along x
    cells: Tensor  # float32 [(H - 1) * (W - 1), 4]
    valued: Tensor  # bool [(H - 1) * (W - 1)]

    @classmethod
    def build(
        cls,
        start: Tensor,
        end: Tensor,
        *,
        cover: Tensor | None = None,
        resolution: float = RESOLUTION,
        margin: float = MARGIN,
        max_nodes: int = MAX_NODES,
    ) -> RoadField:
        """The field of the road-edge segments start, end [K, 2] (K > 0; edges keep the road on their left)
        over their bounding box and the points `cover` [N, 2] (the agents, say), `margin` m around."""
        if start.ndim != 2 or start.shape[-1] != 2 or start.shape != end.shape or start.shape[0] == 0:
            raise InputError(f"segments must be two non-empty [K, 2] tensors, got {tuple(start.shape)}, {end.shape}")
        if not (resolution > 0 and margin >= 0 and max_nodes >= 4):
            raise InputError(
                f"need resolution > 0, margin >= 0, max_nodes >= 4; got {resolution}, {margin}, {max_nodes}"
            )
        a = start.detach().double().cpu().numpy()
        b = end.detach().double().cpu().numpy()
        if not (np.isfinite(a).all() and np.isfinite(b).all()):
            raise InputError("road-edge segment end points must be finite")
        corners = [a, b]
        if cover is not None and cover.numel():
            extra = cover.detach().double().cpu().numpy().reshape(-1, 2)
            corners.append(extra[np.isfinite(extra).all(-1)])
        low = np.min([c.min(0) for c in corners if len(c)], axis=0) - margin
        extent = np.max([c.max(0) for c in corners if len(c)], axis=0) + margin - low
        spacing = max(float(resolution), float(np.sqrt(extent[0] * extent[1] / max_nodes)))
        while np.prod(_grid_shape(extent, spacing)) > max_nodes:
            spacing *= 1.05
        height, width = _grid_shape(extent, spacing)

        # Samples every _SAMPLE m along each segment (both ends included), each knowing its segment.
        length = np.linalg.norm(b - a, axis=-1)
        count = np.ceil(length / _SAMPLE).astype(np.int64) + 1
        owner = np.repeat(np.arange(len(a)), count)
        first = np.cumsum(count) - count
        fraction = (np.arange(owner.size) - first[owner]) / np.maximum(count[owner] - 1, 1)
        samples = a[owner] + fraction[:, None] * (b - a)[owner]
        # Every node's distance to the nearest rasterized sample and that sample (scipy's exact Euclidean
        # distance transform; within about a spacing of the true distance to the edges) ...
        cell = np.rint((samples - low) / spacing).astype(np.int64)
        raster = np.full((height, width), -1, np.int64)
        raster[cell[:, 1], cell[:, 0]] = np.arange(len(samples))
        rough, (iy, ix) = ndimage.distance_transform_edt(raster < 0, sampling=spacing, return_indices=True)
        nearest = raster[iy, ix].reshape(-1)
        rough = rough.reshape(-1)
        # ... whose segment gives the value of the nodes farther than _BAND m from every edge; the nodes
        # within _BAND m, where the cost is decided, get exact distances to the nearest of the segments of
        # their nearest samples (a k-d tree search) and those segments' polyline neighbours.
        neighbours = polyline_neighbours(a, b)
        values = np.full(height * width, np.nan, np.float32)  # beyond _FAR m: left to the exact search
        far = np.flatnonzero((rough >= _BAND) & (rough < _FAR))
        xy = np.stack([far % width, far // width], -1) * spacing + low
        values[far] = signed_distance(xy, a, b, owner[nearest[far], None])
        near = np.flatnonzero(rough < _BAND)
        tree = cKDTree(samples)
        k = min(_NEAREST, len(samples))
        for lo in range(0, len(near), _CHUNK):
            node = near[lo : lo + _CHUNK]
            xy = np.stack([node % width, node // width], -1) * spacing + low
            _, close = tree.query(xy, k=k)
            found = np.concatenate([nearest[node, None], close.reshape(len(node), k)], -1)
            options = neighbours[owner[found]].reshape(len(node), -1)  # their segments and polyline neighbours
            values[node] = signed_distance(xy, a, b, options)
        grid = values.reshape(height, width)
        corners = [grid[:-1, :-1], grid[:-1, 1:], grid[1:, :-1], grid[1:, 1:]]
        cells = np.stack([c.reshape(-1) for c in corners], -1)
        valued = np.isfinite(cells).all(-1)
        return cls(
            origin=torch.as_tensor(low, dtype=torch.float64),
            resolution=spacing,
            shape=(height, width),
            cells=torch.as_tensor(np.nan_to_num(cells, nan=0.0)),
            valued=torch.as_tensor(valued),
        )

    def sample(self, points: Tensor) -> tuple[Tensor, Tensor]:
        """Bilinear signed distance at `points` [..., 2] (differentiable in them; 0 where the field has no
        value), and bool [...]: where it has one (inside the grid, not farther than `_FAR` m from every
        edge)."""
        height, width = self.shape
        local = (points - self.origin.to(points)) / self.resolution
        corner = torch.floor(local.detach())
        # NaN and infinite coordinates fail the bounds themselves.
        inside = (
            (corner[..., 0] >= 0)
            & (corner[..., 1] >= 0)
            & (corner[..., 0] <= width - 2)
            & (corner[..., 1] <= height - 2)
        )
        everywhere = bool(inside.all())
        if not everywhere:
            corner = torch.where(inside[..., None], corner, torch.zeros_like(corner))
        cell = (corner[..., 1] * (width - 1) + corner[..., 0]).long().reshape(-1)
        valued = self.valued.index_select(0, cell).view(inside.shape)
        if not bool(valued.all()):
            inside, everywhere = inside & valued, False
        t = local - corner  # in [0, 1] inside the grid
        if not everywhere:
            t = torch.where(inside[..., None], t, torch.zeros_like(t))
        v00, v01, v10, v11 = self.cells.to(points.dtype).index_select(0, cell).unbind(-1)
        tx, ty = t[..., 0].reshape(-1), t[..., 1].reshape(-1)
        value = ((v00 + (v01 - v00) * tx) * (1 - ty) + (v10 + (v11 - v10) * tx) * ty).view(inside.shape)
        return (value if everywhere else torch.where(inside, value, torch.zeros_like(value))), inside

    def to(self, device: torch.device | str) -> RoadField:
        """The field with its tensors on `device`."""
        return replace(self, origin=self.origin.to(device), cells=self.cells.to(device), valued=self.valued.to(device))


def _grid_shape(extent: np.ndarray, spacing: float) -> tuple[int, int]:
    """(H, W): the nodes `spacing` apart that span `extent` (x, y metres)."""
    return int(np.ceil(extent[1] / spacing)) + 1, int(np.ceil(extent[0] / spacing)) + 1


def polyline_neighbours(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """[K, 3]: each segment, the one before it and the one after it where consecutive segments join (the
    end of one is the start of the next, as `GuidanceScene` lays polylines out), else itself."""
    index = np.arange(len(start))
    joined = np.zeros(len(start), bool)
    joined[:-1] = np.all(end[:-1] == start[1:], axis=-1)  # segment s continues into s + 1
    before = np.where(np.concatenate([[False], joined[:-1]]), index - 1, index)
    after = np.where(joined, index + 1, index)
    return np.stack([index, before, after], -1)


def signed_distance(points: np.ndarray, start: np.ndarray, end: np.ndarray, options: np.ndarray) -> np.ndarray:
    """Signed distance of points [n, 2] to the nearest of their candidate segments `options` (long [n, c]
    into start, end [K, 2]): negative on the segment's left (the road side), as `OnRoadCost`; a point on the
    line of its segment (beyond an end) counts as off the road."""
    if len(points) == 0:
        return np.zeros(0)
    found = project_on_segments(points[:, None], start[options], end[options])  # [n, c]
    pick = found.distance.argmin(-1)
    rows = np.arange(len(points))
    distance = found.distance[rows, pick]
    return np.where(found.side[rows, pick] > 0, -distance, distance)
