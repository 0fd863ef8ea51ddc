"""The static map layer: every map feature added to an Axes once, as a few grouped collections.

Grouping by style keeps the artist count small (one LineCollection or PolyCollection per style),
which is what makes redrawing the map per frame cheap.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection, PolyCollection

from langtraj.scenario.model import RoadMap
from langtraj.scenario.types import MapFeatureType
from langtraj.viz import style


def _lines(ax: Axes, lines: list[np.ndarray], st: style.LineStyle) -> None:
    linestyle = "solid" if st.dashes is None else (0.0, st.dashes)
    ax.add_collection(
        LineCollection(
            lines,
            colors=st.color,
            linewidths=st.width,
            linestyles=linestyle,
            alpha=st.alpha,
            zorder=st.zorder,
            capstyle="butt",
            joinstyle="round",
        ),
        autolim=False,
    )


def _areas(ax: Axes, polygons: list[np.ndarray], st: style.AreaStyle) -> None:
    coll = PolyCollection(
        polygons,
        closed=True,
        facecolors=st.face,
        edgecolors=st.edge,
        linewidths=st.width,
        alpha=st.alpha,
        zorder=st.zorder,
    )
    if st.hatch:
        coll.set_hatch(st.hatch)
        coll.set_hatchcolor(st.edge)
        coll.set_hatch_linewidth(st.width)
    ax.add_collection(coll, autolim=False)


def add_map(ax: Axes, road_map: RoadMap) -> None:
    """Draw lanes, road lines, road edges, crosswalks, speed bumps, driveways and stop signs."""
    lines: dict[style.LineStyle, list[np.ndarray]] = defaultdict(list)
    areas: dict[style.AreaStyle, list[np.ndarray]] = defaultdict(list)
    edges: list[np.ndarray] = []
    stop_signs: list[np.ndarray] = []
    for feature in road_map:
        ftype, pts = feature.type, feature.points[:, :2]
        if feature.polygon is not None and len(feature.polygon) >= 3:
            areas[style.LANE_SURFACE].append(feature.polygon[:, :2])
        if ftype == MapFeatureType.STOP_SIGN:
            if len(pts):
                stop_signs.append(pts[0])
        elif ftype.is_area:
            if len(pts) >= 3:
                areas[style.AREA_STYLES[ftype]].append(pts)
        elif len(pts) >= 2:
            st = style.line_style(ftype)
            if st is not None:
                lines[st].append(pts)
                if ftype.is_road_edge:
                    edges.append(pts)
    for area_style, polygons in areas.items():
        _areas(ax, polygons, area_style)
    if edges:
        _lines(ax, edges, style.ROAD_EDGE_UNDERLAY)
    for line_style, group in lines.items():
        _lines(ax, group, line_style)
    if stop_signs:
        xy = np.asarray(stop_signs)
        ax.scatter(
            xy[:, 0],
            xy[:, 1],
            s=style.STOP_SIGN_SIZE,
            marker="8",
            c=style.STOP_SIGN_COLOR,
            edgecolors=style.STOP_SIGN_EDGE,
            linewidths=0.8,
            zorder=style.STOP_SIGN_ZORDER,
        )
