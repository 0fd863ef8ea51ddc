"""SUMO network -> LangTraj map model (WOMD's map): lanes, road lines, road edges, crosswalks, stop signs.

`build_net_map` reads a `.net.xml` once per simulated network; `crop_road_map` cuts the map of one
window out of it. Coordinates are SUMO net coordinates (x east, y north, metres); z is 0 unless the
net has elevation (lanes only; road edges, road lines and crosswalks are flat).

Conventions (WOMD-like):
- Every polyline is resampled so consecutive points are at most `point_spacing` apart (WOMD samples
  its map at about 0.5 m), so a window crop by "any point inside" keeps every feature that crosses it.
- Lanes: every lane a road vehicle or bicycle may use, junction-internal lanes included; those inside
  intersections (not merges, splits or mid-block crossings) are `interpolating`, as in WOMD; sidewalks,
  crossings and walking areas are not lanes.
- Road edges are the boundary of the drivable area (the union of all lane surfaces and the junction
  areas less their walking areas). Every ring runs with the drivable area on its LEFT (WOSAC's
  convention: port side on-road): outer rings counter-clockwise (ROAD_EDGE_BOUNDARY), holes clockwise
  (ROAD_EDGE_MEDIAN when narrow: medians, traffic and roundabout islands; ROAD_EDGE_BOUNDARY when wide:
  city blocks, see `MEDIAN_MAX_HALF_WIDTH_M`). A ring up to `MAX_EDGE_PIECE_M` long is one closed
  polyline (first point == last point); a longer one is split into pieces that share their end points.
- Lane boundaries point at road lines with their own type, and at road edges with type
  ROAD_LINE_UNKNOWN (as in WOMD, whose boundary segments carry a road-line type only).

See docs/data.md.

The package: `common` (constants, `NetMap`), `geometry` (polylines), `network` (reading the net),
`lines` (road lines and edges), `build` (`build_net_map`), `crop` (`crop_road_map`).
"""

from __future__ import annotations

from langtraj.synth.mapping.build import build_net_map
from langtraj.synth.mapping.common import NetMap
from langtraj.synth.mapping.crop import crop_road_map

__all__ = ["NetMap", "build_net_map", "crop_road_map"]
