"""Field-by-field comparison of two scenarios, for round-trip checks of readers and converters. See docs/data.md."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from langtraj.scenario.model import MapFeature, Scenario


def _array_diff(name: str, a: np.ndarray, b: np.ndarray, atol: float) -> list[str]:
    if a.shape != b.shape:
        return [f"{name}: shape {a.shape} != {b.shape}"]
    if a.dtype.kind == "f" or b.dtype.kind == "f":
        same = np.isclose(a, b, rtol=0.0, atol=atol, equal_nan=True)
    else:
        same = a == b
    if np.all(same):
        return []
    first = tuple(int(i) for i in np.argwhere(~np.asarray(same))[0])
    return [f"{name}: {int((~np.asarray(same)).sum())} values differ, first at {first}: {a[first]} != {b[first]}"]


def _feature_diff(a: MapFeature, b: MapFeature, atol: float, compare_polygons: bool) -> list[str]:
    name = f"map feature {a.id}"
    out: list[str] = []
    for f in dataclasses.fields(MapFeature):
        if f.name == "polygon" and not compare_polygons:
            continue
        va, vb = getattr(a, f.name), getattr(b, f.name)
        if f.name in ("points", "polygon"):
            if va is None or vb is None:
                if (va is None) != (vb is None):
                    out.append(f"{name}.{f.name}: present on one side only")
                continue
            out += _array_diff(f"{name}.{f.name}", va, vb, atol)
        elif f.name == "speed_limit_mph":
            if not (va == vb or (math.isnan(va) and math.isnan(vb))):
                out.append(f"{name}.speed_limit_mph: {va} != {vb}")
        elif va != vb:
            out.append(f"{name}.{f.name}: {va!r} != {vb!r}")
    return out


def scenario_differences(
    a: Scenario,
    b: Scenario,
    *,
    atol: float = 0.0,
    compare_invalid_states: bool = True,
    compare_metadata: bool = True,
    compare_polygons: bool = True,
) -> list[str]:
    """Human-readable differences between two scenarios (empty when they are equal).

    `atol` applies to float arrays. With `compare_invalid_states=False`, state values at invalid
    steps are ignored (formats disagree on what to store there). `compare_metadata` and
    `compare_polygons` (lane outlines) can be switched off for formats that cannot hold them.
    """
    out: list[str] = []
    for name in ("scenario_id", "current_index", "sdc_index"):
        if getattr(a, name) != getattr(b, name):
            out.append(f"{name}: {getattr(a, name)!r} != {getattr(b, name)!r}")
    out += _array_diff("timestamps", a.timestamps, b.timestamps, atol)
    for name in (
        "ids",
        "types",
        "valid",
        "tracks_to_predict",
        "prediction_difficulty",
        "objects_of_interest",
    ):
        out += _array_diff(f"agents.{name}", getattr(a.agents, name), getattr(b.agents, name), 0.0)
    sa, sb = a.agents.states, b.agents.states
    if not compare_invalid_states and a.agents.valid.shape == b.agents.valid.shape:
        mask = a.agents.valid[..., None] & b.agents.valid[..., None]
        sa, sb = np.where(mask, sa, 0.0), np.where(mask, sb, 0.0)
    out += _array_diff("agents.states", sa, sb, atol)
    ids_a = [f.id for f in a.road_map]
    ids_b = [f.id for f in b.road_map]
    if ids_a != ids_b:
        out.append(f"road_map: feature ids differ ({len(ids_a)} vs {len(ids_b)} features)")
    else:
        for fa, fb in zip(a.road_map, b.road_map, strict=True):
            out += _feature_diff(fa, fb, atol, compare_polygons)
    la, lb = a.traffic_lights, b.traffic_lights
    for name in ("lane_ids", "states", "valid", "stop_points"):
        out += _array_diff(f"traffic_lights.{name}", getattr(la, name), getattr(lb, name), atol)
    if a.events != b.events:
        out.append(f"events: {len(a.events)} vs {len(b.events)} events, or their fields differ")
    if compare_metadata and dict(a.metadata) != dict(b.metadata):
        out.append("metadata differs")
    return out
