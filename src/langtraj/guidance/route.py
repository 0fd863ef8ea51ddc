"""Costs along a route: drive on a given path, get past or stay before a station of it.

A route is a polyline in the scene frame (a target's path, `interdrive.targets`): the lanes of a turn's branch,
the neighbour lane of a lane change, the kerb line of a pull-over. `RouteCost` pulls an agent onto it and
`StationCost` moves the agent along it (reach a station by a step) or holds it back (stay before a station: a
stop point, a conflict point). Both are the kind of cost CTG++ writes for an instruction, built from the map.

See docs/simulation.md ('Prompts that steer').
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Sequence
from typing import Literal

import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.guidance.base import GUIDANCE, GuidanceCost, as_slot, check_slots, check_states, window
from langtraj.guidance.geometry import closest_on_segments, nearest_segment
from langtraj.guidance.scene import GuidanceScene

_EPS = 1e-6


def _path(cost: str, points: Sequence[Sequence[float]] | Tensor) -> Tensor:
    path = torch.as_tensor(points, dtype=torch.float32)
    if path.ndim != 2 or path.shape[1] != 2 or path.shape[0] < 2 or not torch.isfinite(path).all():
        raise InputError(f"{cost}: path must be at least two finite (x, y) points, got shape {tuple(path.shape)}")
    return path


class _RouteCost(GuidanceCost):
    """What both route costs share: one steered slot, a path and a window of steps [start, end)."""

    def __init__(self, slot: int, path: Sequence[Sequence[float]] | Tensor, *, start: int = 0, end: int | None = None):
        self.slot = as_slot(self.name, slot)
        self.slots = (self.slot,)
        self.path = _path(self.name, path)
        self.start, self.end = window(self.name, start, end)
        lengths = (self.path[1:] - self.path[:-1]).norm(dim=-1)
        self.arc = torch.cat([lengths.new_zeros(1), lengths.cumsum(0)])

    def __call__(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        check_states(self.name, states, scene)
        check_slots(self.name, self.slots, states.shape[1])
        if not bool(scene.agent_valid[self.slot]) or self.start >= states.shape[2]:
            return states.sum(dim=(1, 2, 3)) * 0.0  # padding, or a window past the horizon: no cost, in the graph
        return self._cost(states[:, self.slot, self.start : self.end, :2])

    @abstractmethod
    def _cost(self, xy: Tensor) -> Tensor:
        """The cost [S] of the slot's positions [S, W, 2] in the window."""

    def _offset_and_station(self, xy: Tensor) -> tuple[Tensor, Tensor]:
        """Offset vectors [..., 2] from the path and arc length [...] along it of points `xy` [..., 2]."""
        path = self.path.to(xy)
        start, end = path[:-1], path[1:]
        index = nearest_segment(xy, start, end)
        closest = closest_on_segments(xy, start[index], end[index])
        direction = end[index] - start[index]
        along = ((xy - start[index]) * direction).sum(-1) / direction.norm(dim=-1).clamp(min=1e-9)
        return xy - closest, self.arc.to(xy)[index] + along


@GUIDANCE.register
class RouteCost(_RouteCost):
    """Drive along `path` (scene frame): agent `slot`'s squared distance to the polyline, averaged over the steps
    [start, end); beyond `cap` m it grows linearly (a Huber loss), so an agent far off the route is pulled
    without an exploding gradient."""

    name = "route"

    def __init__(
        self,
        slot: int,
        path: Sequence[Sequence[float]] | Tensor,
        *,
        start: int = 0,
        end: int | None = None,
        cap: float = 3.0,
    ):
        super().__init__(slot, path, start=start, end=end)
        if not cap > 0:
            raise InputError(f"{self.name}: cap must be > 0, got {cap}")
        self.cap = float(cap)

    def _cost(self, xy: Tensor) -> Tensor:
        offset, _ = self._offset_and_station(xy)
        distance = torch.sqrt((offset**2).sum(-1) + _EPS)
        huber = torch.where(distance <= self.cap, distance**2, self.cap * (2 * distance - self.cap))
        return huber.mean(-1)


@GUIDANCE.register
class StationCost(_RouteCost):
    """Progress along `path`: with `mode` "reach", agent `slot` is at least `station` m along it at every step of
    [start, end) (get past a junction's exit by then); with "hold", at most `station` m (stay before a stop or
    conflict point). The cost is the mean squared shortfall or overshoot in metres."""

    name = "station"

    def __init__(
        self,
        slot: int,
        path: Sequence[Sequence[float]] | Tensor,
        station: float,
        *,
        mode: Literal["reach", "hold"] = "reach",
        start: int = 0,
        end: int | None = None,
    ):
        super().__init__(slot, path, start=start, end=end)
        if mode not in ("reach", "hold"):
            raise InputError(f"{self.name}: mode must be 'reach' or 'hold', got {mode!r}")
        self.mode = mode
        self.station = float(station)

    def _cost(self, xy: Tensor) -> Tensor:
        _, along = self._offset_and_station(xy)
        miss = self.station - along if self.mode == "reach" else along - self.station
        return (torch.relu(miss) ** 2).mean(-1)
