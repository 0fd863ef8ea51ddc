"""The road network as a layer of its own (docs/design.md, 'Layers'): map queries and lane primitives built once per
scene over a `RoadMap` (`MapIndex`), and paths drawn along the lane graph (`roads.routes`). The labelers
(`interdrive`), the simulation (`sim`) and the environment (`env`) all read the road from here; it reads nothing
above `scenario`.

Lanes and road edges are resampled to short segments (at most `SEGMENT_SPACING_M` long) and bucketed in a
uniform grid, so a batch of positions is matched to its nearest segments by vectorised numpy (no scipy).

What each query relies on, and what it falls back to (each `*_source` attribute names it):
- junction lanes: `MapFeature.interpolating` when any lane of the map sets it (WOMD v1.1+, synthesized maps);
  otherwise geometry: a lane whose centerline crosses another lane's centerline at 30 degrees or more
  (away from both lanes' ends, so lanes that merge or fan out from a shared point do not count), or a short
  lane that turns sharply (at least 60 degrees within 40 m).
- lane neighbours: `left_neighbors` / `right_neighbors` where the map has any; optionally (`infer_neighbors`)
  geometry: a same-direction lane whose centerline runs 2.5-4.5 m beside this one; otherwise none. The detector
  asks per lane pair instead (`neighbor_side` with `per_lane`).
- parked vehicles: `parked_decision`, whether a vehicle standing all window is at the road side.
- lane changes: both labelers report them as `LaneChange`.
- lane connectivity (distance to the next junction): `exit_lanes` / `entry_lanes` only.
- crosswalks and road edges: the `CROSSWALK` polygons and `ROAD_EDGE_*` polylines, where the map has any.

Modules: `segments` (`SegmentSet`, the grid of short segments), `records` (`LaneMatch`, `LaneChange`), `lane_graph`
(lane links, neighbour spans, junction lanes, derived at build time), `index` (`MapIndex` and its queries), `routes`
(a lane's centreline from a station, a route along lanes continued by the straightest exits, a straight line),
`stop_lines` (`StopLines`, where traffic stops for a stop sign or a signal).
"""

from langtraj.polylines import arc_lengths  # re-exported for the modules that still import it from here
from langtraj.roads.index import MapIndex
from langtraj.roads.records import LaneChange, LaneMatch
from langtraj.roads.segments import SEGMENT_SPACING_M, SegmentSet

__all__ = [
    "SEGMENT_SPACING_M",
    "LaneChange",
    "LaneMatch",
    "MapIndex",
    "SegmentSet",
    "arc_lengths",
]
