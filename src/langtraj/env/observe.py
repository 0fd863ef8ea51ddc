"""Ego-centred observations of a simulated scene (docs/testing.md, 'Observations'): the ego, its route, the
nearest agents, the map and the traffic lights around it, in the fixed shapes of `env.spaces`.

The map is cut once per episode into pieces of `POLYLINE_POINTS` points as the model's map is cut
(`model.features.feature_pieces`), so each step only picks the nearest pieces. Traffic lights are those of the step,
replayed from the log as Waymax and nuPlan replay them (`lights="log"`, the default: a signal is the environment's,
not an agent's future), or held at their state at the start (`lights="held"`; `env.rules.LIGHT_MODES`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.env import spaces
from langtraj.env.rules import EpisodeLights
from langtraj.env.spaces import AgentColumn, EgoColumn
from langtraj.frames import points_to_frame
from langtraj.model.features import feature_pieces
from langtraj.roads.mission import Route
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import StateField


def to_ego_frame(xy: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """World points [..., 2] in the frame of `pose` (x, y, heading): x forward, y left."""
    return points_to_frame(xy, (float(pose[0]), float(pose[1]), float(pose[2])))


@dataclass(frozen=True)
class MapPieces:
    """Every map feature cut into pieces of `POLYLINE_POINTS` points (`model.features.feature_pieces`)."""

    points: np.ndarray  # float64 [N, P, 2] (a feature of no length: its one point repeated)
    valid: np.ndarray  # bool [N, P]
    types: np.ndarray  # int64 [N]

    @classmethod
    def of(cls, scenario: Scenario) -> MapPieces:
        size, pieces, valid, types = spaces.POLYLINE_POINTS, [], [], []
        for feature in scenario.road_map.features:
            line = np.asarray(feature.points[:, :2], np.float64)
            if not len(line):
                continue
            for part in feature_pieces(line, feature.type, size):
                pieces.append(np.repeat(part, size, axis=0) if len(part) == 1 else part)
                valid.append(np.arange(size) < len(part))
                types.append(int(feature.type))
        if not pieces:
            return cls(np.zeros((0, size, 2)), np.zeros((0, size), bool), np.zeros(0, np.int64))
        return cls(np.stack(pieces), np.stack(valid), np.asarray(types, np.int64))


class Observer:
    """Builds the observation of the ego (scenario row `ego`) from the world's states at a step."""

    def __init__(
        self,
        scenario: Scenario,
        ego: int,
        route: Route,
        pieces: MapPieces | None = None,
        lights: EpisodeLights | None = None,
    ):
        self.ego = ego
        self.route = route
        self.pieces = MapPieces.of(scenario) if pieces is None else pieces
        self.ids = scenario.agents.ids.astype(np.int64)
        self.types = scenario.agents.types.astype(np.int64)
        self.lights = EpisodeLights(scenario) if lights is None else lights

    def observe(
        self,
        states: np.ndarray,
        valid: np.ndarray,
        time: float,
        control: np.ndarray,
        history: tuple[np.ndarray, np.ndarray] | None = None,
        step: int | None = None,
    ) -> tuple[dict[str, np.ndarray], float]:
        """The observation from every agent's state [A, 9] and validity [A] at one step, the time since the start,
        the control the ego executed last and `history`, every agent's states [A, H, 9] and validity [A, H] at the
        steps before (the last `spaces.HISTORY_STEPS` used; None: none seen); and the ego's station along its
        route."""
        me = states[self.ego].astype(np.float64)
        speed = float(np.hypot(me[StateField.VX], me[StateField.VY]))
        pose = me[[StateField.X, StateField.Y, StateField.HEADING]]
        ego = np.zeros(len(EgoColumn))
        ego[[EgoColumn.X, EgoColumn.Y, EgoColumn.HEADING]] = pose
        ego[EgoColumn.SPEED], ego[EgoColumn.ACCELERATION], ego[EgoColumn.YAW_RATE] = speed, control[0], control[1]
        ego[EgoColumn.LENGTH], ego[EgoColumn.WIDTH] = me[StateField.LENGTH], me[StateField.WIDTH]
        station = self.route.station(pose[:2])
        route_xy, route_valid, limits = self.route.ahead(station, spaces.NUM_ROUTE_POINTS, spaces.ROUTE_SPACING_M)
        obs = {
            "ego": ego.astype(np.float32),
            "time": np.array([time], np.float32),
            "route": np.where(route_valid[:, None], to_ego_frame(route_xy, pose), 0.0).astype(np.float32),
            "route_valid": route_valid.astype(np.int8),
            "route_speed_limit": np.nan_to_num(limits, nan=0.0).astype(np.float32),
        }
        obs |= self._agents(states, valid, pose, history)
        obs |= self._map(pose)
        obs |= self._lights(pose, self.lights.start if step is None else step)
        return obs, station

    def _agents(
        self, states: np.ndarray, valid: np.ndarray, pose: np.ndarray, history: tuple[np.ndarray, np.ndarray] | None
    ) -> dict[str, np.ndarray]:
        k = spaces.NUM_AGENTS
        rows = np.flatnonzero(valid)
        rows = rows[rows != self.ego]
        dist = np.hypot(states[rows, StateField.X] - pose[0], states[rows, StateField.Y] - pose[1])
        near = dist <= spaces.AGENT_RADIUS_M
        rows, dist = rows[near], dist[near]
        rows = rows[np.argsort(dist, kind="stable")[:k]]
        s = states[rows].astype(np.float64)
        c, si = np.cos(pose[2]), np.sin(pose[2])
        vx, vy = s[:, StateField.VX], s[:, StateField.VY]
        heading = wrap_angle(s[:, StateField.HEADING] - pose[2])
        table = np.zeros((k, len(AgentColumn)), np.float32)
        n = len(rows)
        table[:n, [AgentColumn.X, AgentColumn.Y]] = to_ego_frame(s[:, [StateField.X, StateField.Y]], pose)
        table[:n, AgentColumn.HEADING] = heading
        table[:n, AgentColumn.VX], table[:n, AgentColumn.VY] = c * vx + si * vy, -si * vx + c * vy
        table[:n, AgentColumn.LENGTH], table[:n, AgentColumn.WIDTH] = s[:, StateField.LENGTH], s[:, StateField.WIDTH]
        ids, types, mask = np.full(k, -1, np.int64), np.zeros(k, np.int64), np.zeros(k, np.int8)
        ids[: len(rows)], types[: len(rows)], mask[: len(rows)] = self.ids[rows], self.types[rows], 1
        h = spaces.HISTORY_STEPS
        past, seen = np.zeros((k, h, 2), np.float32), np.zeros((k, h), np.int8)
        if history is not None and n:
            old, old_valid = history[0][rows, -h:], history[1][rows, -h:].astype(bool)  # [n, <=H, 9], [n, <=H]
            steps = old.shape[1]
            xy = to_ego_frame(old[..., [StateField.X, StateField.Y]].reshape(-1, 2).astype(np.float64), pose)
            past[:n, h - steps :] = np.where(old_valid[..., None], xy.reshape(n, steps, 2), 0.0)
            seen[:n, h - steps :] = old_valid
        return {
            "agents": table,
            "agents_id": ids,
            "agents_type": types,
            "agents_valid": mask,
            "agents_history": past,
            "agents_history_valid": seen,
        }

    def _map(self, pose: np.ndarray) -> dict[str, np.ndarray]:
        n, p = spaces.NUM_POLYLINES, spaces.POLYLINE_POINTS
        out = {"map": np.zeros((n, p, 2), np.float32), "map_type": np.zeros(n, np.int64)}
        out["map_valid"] = np.zeros((n, p), np.int8)
        pieces = self.pieces
        if not len(pieces.types):
            return out
        dist = np.hypot(pieces.points[..., 0] - pose[0], pieces.points[..., 1] - pose[1])
        inside = pieces.valid & (dist <= spaces.MAP_RADIUS_M)
        nearest = np.where(inside, dist, np.inf).min(-1)
        chosen = np.flatnonzero(np.isfinite(nearest))
        chosen = chosen[np.argsort(nearest[chosen], kind="stable")[:n]]
        m = len(chosen)
        mask = inside[chosen]
        out["map"][:m] = np.where(mask[..., None], to_ego_frame(pieces.points[chosen], pose), 0.0)
        out["map_type"][:m] = pieces.types[chosen]
        out["map_valid"][:m] = mask
        return out

    def _lights(self, pose: np.ndarray, step: int) -> dict[str, np.ndarray]:
        """The nearest lights and their states at `step`, as the episode sees them (`EpisodeLights`)."""
        k = spaces.NUM_LIGHTS
        out = {"lights": np.zeros((k, 2), np.float32), "lights_state": np.zeros(k, np.int64)}
        out["lights_valid"] = np.zeros(k, np.int8)
        if self.lights.log is None:
            return out
        states, keep = self.lights.at(step)
        points, states = np.asarray(self.lights.log.stop_points[keep, :2], np.float64), states[keep].astype(np.int64)
        if not len(states):
            return out
        dist = np.hypot(*(points - pose[:2]).T)
        order = np.argsort(dist, kind="stable")[:k]
        order = order[dist[order] <= spaces.MAP_RADIUS_M]
        out["lights"][: len(order)] = to_ego_frame(points[order], pose)
        out["lights_state"][: len(order)] = states[order]
        out["lights_valid"][: len(order)] = 1
        return out
