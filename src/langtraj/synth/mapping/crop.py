"""Cropping a road map to a window's box (`crop_road_map`), with a cached point index.
See docs/data.md.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from langtraj.scenario.model import BoundarySegment, LaneNeighbor, MapFeature, RoadMap

# ---------------------------------------------------------------------------------------------- cropping


@dataclass(frozen=True, eq=False)
class _MapIndex:
    """All map points of a road map in one array, with the index of the feature each belongs to."""

    xy: np.ndarray  # float64 [P, 2]
    owner: np.ndarray  # int64 [P]
    refs: tuple[frozenset[int], ...]  # per feature: the feature ids it references


_INDEX_CACHE: weakref.WeakKeyDictionary[RoadMap, _MapIndex] = weakref.WeakKeyDictionary()


def _references(feature: MapFeature) -> frozenset[int]:
    ids = set(feature.entry_lanes) | set(feature.exit_lanes) | set(feature.controlled_lanes)
    for nb in (*feature.left_neighbors, *feature.right_neighbors):
        ids.add(nb.feature_id)
        ids.update(s.boundary_feature_id for s in nb.boundaries)
    ids.update(s.boundary_feature_id for s in (*feature.left_boundaries, *feature.right_boundaries))
    return frozenset(ids)


def _map_index(road_map: RoadMap) -> _MapIndex:
    index = _INDEX_CACHE.get(road_map)
    if index is None:
        features = road_map.features
        counts = np.array([len(f.points) for f in features], np.int64)
        xy = np.concatenate([f.points[:, :2] for f in features]) if len(features) else np.zeros((0, 2))
        owner = np.repeat(np.arange(len(features)), counts)
        index = _MapIndex(xy, owner, tuple(_references(f) for f in features))
        _INDEX_CACHE[road_map] = index
    return index


def _without(feature: MapFeature, kept: set[int]) -> MapFeature:
    """The feature with every reference to a feature outside `kept` removed."""

    def segs(items: Iterable[BoundarySegment]) -> tuple[BoundarySegment, ...]:
        return tuple(s for s in items if s.boundary_feature_id in kept)

    def nbs(items: Iterable[LaneNeighbor]) -> tuple[LaneNeighbor, ...]:
        return tuple(replace(n, boundaries=segs(n.boundaries)) for n in items if n.feature_id in kept)

    return replace(
        feature,
        entry_lanes=tuple(i for i in feature.entry_lanes if i in kept),
        exit_lanes=tuple(i for i in feature.exit_lanes if i in kept),
        controlled_lanes=tuple(i for i in feature.controlled_lanes if i in kept),
        left_neighbors=nbs(feature.left_neighbors),
        right_neighbors=nbs(feature.right_neighbors),
        left_boundaries=segs(feature.left_boundaries),
        right_boundaries=segs(feature.right_boundaries),
    )


def crop_road_map(road_map: RoadMap, xy_min: Sequence[float], xy_max: Sequence[float]) -> RoadMap:
    """The features with any point inside the box [xy_min, xy_max], references to dropped features removed.

    Cheap per call (the point index of `road_map` is built once and cached), so windows can crop freely.
    """
    index = _map_index(road_map)
    lo, hi = np.asarray(xy_min, np.float64)[:2], np.asarray(xy_max, np.float64)[:2]
    inside = np.all((index.xy >= lo) & (index.xy <= hi), axis=1)
    keep = np.unique(index.owner[inside])
    features = road_map.features
    kept = {features[i].id for i in keep.tolist()}
    out = []
    for i in keep.tolist():
        feature = features[i]
        out.append(feature if index.refs[i] <= kept else _without(feature, kept))
    return RoadMap(tuple(out))
