"""The static part of a scene that guidance costs look at: road edges, lane centres and agent sizes.

Everything is in one scene frame (the frame of the model's `SceneBatch` row), so costs compare it
directly with the rolled-out states. Build it from a Scenario (`from_scenario`, the whole map) or from
one row of a SceneBatch (`from_batch`, the polylines the model sees); a scene that many cost calls will
share (a simulation's) gets its road edges' signed distance field once with `with_road_field`.

See docs/simulation.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields, replace

import numpy as np
import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.frames import points_to_frame
from langtraj.guidance.road_field import RoadField
from langtraj.model.batch import SceneBatch
from langtraj.scenario.drivable import measured_road_edges
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import MapFeatureType, StateField


@dataclass(frozen=True, eq=False)
class GuidanceScene:
    """Map and agent geometry of one scene, as tensors in its scene frame.

    `road_edges[e]` is one road-edge segment (start, end); edges keep the road on their left (the WOMD
    and WOSAC convention). `lanes[l, p]` are lane-centre polylines padded to a common length,
    `lane_valid` marks real points. `agent_size[a]` is (length, width) of model slot `a`; `agent_valid`
    is False for padding slots. `road_field`, when present, is the signed distance field of
    `road_edges` (`with_road_field`) that the on-road cost samples instead of searching the segments.
    """

    road_edges: Tensor  # float [E, 2, 2]
    lanes: Tensor  # float [L, P, 2]
    lane_valid: Tensor  # bool [L, P]
    agent_size: Tensor  # float [A, 2]
    agent_valid: Tensor  # bool [A]
    road_field: RoadField | None = None

    def __post_init__(self) -> None:
        edges, lanes, lane_valid = self.road_edges, self.lanes, self.lane_valid
        size, agent_valid = self.agent_size, self.agent_valid
        if edges.ndim != 3 or edges.shape[1:] != (2, 2):
            raise InputError(f"road_edges must be [E, 2, 2], got {tuple(edges.shape)}")
        if lanes.ndim != 3 or lanes.shape[-1] != 2 or lane_valid.shape != lanes.shape[:2]:
            raise InputError(f"lanes must be [L, P, 2], lane_valid [L, P]; got {lanes.shape}, {lane_valid.shape}")
        if size.ndim != 2 or size.shape[1] != 2 or agent_valid.shape != size.shape[:1]:
            raise InputError(f"agent_size must be [A, 2], agent_valid [A]; got {size.shape}, {agent_valid.shape}")

    @property
    def num_agents(self) -> int:
        return self.agent_valid.shape[0]

    def lane_segments(self) -> tuple[Tensor, Tensor]:
        """Start and end points [K, 2] of every lane segment whose both ends are valid points."""
        keep = self.lane_valid[:, :-1] & self.lane_valid[:, 1:]
        return self.lanes[:, :-1][keep], self.lanes[:, 1:][keep]

    def to(self, device: torch.device | str) -> GuidanceScene:
        """The scene with every tensor (and the road grid) on `device`."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        return replace(self, **{name: v.to(device) for name, v in values.items() if v is not None})

    def with_road_field(self, cover: Tensor | None = None, **options: float) -> GuidanceScene:
        """The scene with the signed distance field of its road edges over them and the points `cover` [N, 2]
        (`RoadField.build(**options)`), built once so that every on-road cost on it samples the field
        instead of searching segments; a scene without road edges is returned as it is."""
        if self.road_edges.shape[0] == 0:
            return self
        edges = self.road_edges
        return replace(self, road_field=RoadField.build(edges[:, 0], edges[:, 1], cover=cover, **options))

    @classmethod
    def from_scenario(
        cls,
        scenario: Scenario,
        origin: Sequence[float] | Tensor,
        agent_indices: Sequence[int] | np.ndarray,
        *,
        num_agents: int | None = None,
        max_lane_points: int = 20,
        radius: float | None = None,
    ) -> GuidanceScene:
        """The scene of `scenario` in the frame `origin` = world (x, y, heading) (e.g. `scene_frame`).

        `agent_indices` are the scenario's agent rows in model slot order; the scene has `num_agents`
        slots (default: one per index) and slots past the indices are invalid padding, as are agents not
        valid at the current step. Every road edge becomes its segments; every lane centre line of two
        or more points is cut into rows of `max_lane_points` points, consecutive rows sharing an end point
        so no segment is lost. With `radius`, only features with a point within `radius` m of the origin
        are kept.
        """
        if max_lane_points < 2:
            raise InputError(f"max_lane_points must be >= 2, got {max_lane_points}")
        frame = tuple(float(v) for v in (origin.tolist() if isinstance(origin, Tensor) else origin))
        if len(frame) != 3:
            raise InputError(f"origin must be (x, y, heading), got {frame}")
        rows = np.asarray(agent_indices, np.int64).reshape(-1)
        slots = len(rows) if num_agents is None else int(num_agents)
        if slots < len(rows):
            raise InputError(f"num_agents {slots} is less than the {len(rows)} agent indices")
        if len(rows) and (rows.min() < 0 or rows.max() >= scenario.num_agents):
            raise InputError(f"agent indices must be in [0, {scenario.num_agents}), got {rows.tolist()}")

        edges = [
            points_to_frame(f.points[:, :2], frame)
            for f in measured_road_edges(scenario)
            if len(f.points) >= 2 and _near(f.points, frame, radius)
        ]
        near = [f for f in scenario.road_map if len(f.points) >= 2 and _near(f.points, frame, radius)]
        segments = [np.stack([p[:-1], p[1:]], axis=1) for p in edges]
        road_edges = np.concatenate(segments) if segments else np.zeros((0, 2, 2))
        step = max_lane_points - 1
        pieces = [
            p[i : i + max_lane_points]
            for p in (points_to_frame(f.points[:, :2], frame) for f in near if f.type.is_lane)
            for i in range(0, len(p) - 1, step)
        ]
        lanes = np.zeros((len(pieces), max_lane_points, 2))
        lane_valid = np.zeros((len(pieces), max_lane_points), bool)
        for row, piece in enumerate(pieces):
            lanes[row, : len(piece)] = piece
            lane_valid[row, : len(piece)] = True

        t = scenario.current_index
        size = np.zeros((slots, 2))
        valid = np.zeros(slots, bool)
        valid[: len(rows)] = scenario.agents.valid[rows, t]
        size[: len(rows)] = scenario.agents.states[rows, t, StateField.LENGTH : StateField.WIDTH + 1]
        size[~valid] = 0.0
        return cls(
            road_edges=torch.as_tensor(road_edges, dtype=torch.float32),
            lanes=torch.as_tensor(lanes, dtype=torch.float32),
            lane_valid=torch.as_tensor(lane_valid),
            agent_size=torch.as_tensor(size, dtype=torch.float32),
            agent_valid=torch.as_tensor(valid),
        )

    @classmethod
    def from_batch(cls, batch: SceneBatch, row: int) -> GuidanceScene:
        """The scene of batch row `row` from the map polylines the model sees (already in the scene frame):
        road-edge polylines become segments, lane polylines stay rows."""
        if not 0 <= row < batch.batch_size:
            raise InputError(f"row {row} is outside [0, {batch.batch_size})")
        points, valid = batch.map_points[row], batch.map_valid[row]
        types = [MapFeatureType(t) if t > 0 else None for t in batch.map_type[row].tolist()]
        mask = {"dtype": torch.bool, "device": points.device}
        is_edge = torch.tensor([t is not None and t.is_road_edge for t in types], **mask)
        is_lane = torch.tensor([t is not None and t.is_lane for t in types], **mask)
        edge_points, edge_valid = points[is_edge], valid[is_edge]
        keep = edge_valid[:, :-1] & edge_valid[:, 1:]
        road_edges = torch.stack([edge_points[:, :-1][keep], edge_points[:, 1:][keep]], dim=1)
        return cls(
            road_edges=road_edges.float(),
            lanes=points[is_lane].float(),
            lane_valid=valid[is_lane],
            agent_size=batch.agent_size[row].float(),
            agent_valid=batch.agent_valid[row],
        )


def _near(points: np.ndarray, origin: tuple[float, ...], radius: float | None) -> bool:
    if radius is None:
        return True
    return bool((np.hypot(points[:, 0] - origin[0], points[:, 1] - origin[1]) <= radius).any())
