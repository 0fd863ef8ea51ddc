"""Costs along a route: drive on a given path, get past or stay before a station of it.

A route is a polyline in the scene frame (a target's path, `interdrive.targets`): the lanes of a turn's branch,
the neighbour lane of a lane change, the kerb line of a pull-over. `RouteCost` pulls an agent onto it and
`StationCost` moves the agent along it (reach a station by a step) or holds it back (stay before a station: a
stop point, a conflict point); `LeadCost` does the same relative to another agent along it (an overtake's gap ahead
of the one overtaken, wherever that one drives). They are the kind of cost CTG++ writes for an instruction, built
from the map.

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
from langtraj.guidance.geometry import offset_and_station
from langtraj.guidance.scene import GuidanceScene

_EPS = 1e-6


def _path(cost: str, points: Sequence[Sequence[float]] | Tensor) -> Tensor:
    path = torch.as_tensor(points, dtype=torch.float32)
    if path.ndim != 2 or path.shape[1] != 2 or path.shape[0] < 2 or not torch.isfinite(path).all():
        raise InputError(f"{cost}: path must be at least two finite (x, y) points, got shape {tuple(path.shape)}")
    return path


class RoutePath:
    """A route's polyline (float32 points [P, 2], P >= 2, scene frame) and the station [P] of each point, built
    once (per steering target: `guidance.steering.Steering.route`) and copied to a device and dtype once, so
    the costs built on it at every replan only set their step windows."""

    def __init__(self, points: Sequence[Sequence[float]] | Tensor, *, cost: str = "route"):
        self.points = _path(cost, points)
        lengths = (self.points[1:] - self.points[:-1]).norm(dim=-1)
        self.arc = torch.cat([lengths.new_zeros(1), lengths.cumsum(0)])
        self._copies: dict[tuple[torch.device, torch.dtype], tuple[Tensor, Tensor, Tensor]] = {}

    def like(self, xy: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        """Segment starts, ends [P - 1, 2] and the stations of the starts [P - 1] on `xy`'s device and in its
        dtype (copied there on first use)."""
        key = (xy.device, xy.dtype)
        if key not in self._copies:
            points = self.points.to(xy)
            self._copies[key] = (points[:-1], points[1:], self.arc.to(xy)[:-1])
        return self._copies[key]


class _RouteCost(GuidanceCost):
    """What both route costs share: one steered slot, a path and a window of steps [start, end)."""

    def __init__(
        self,
        slot: int,
        path: Sequence[Sequence[float]] | Tensor | RoutePath,
        *,
        start: int = 0,
        end: int | None = None,
    ):
        self.slot = as_slot(self.name, slot)
        self.slots = (self.slot,)
        self.route = path if isinstance(path, RoutePath) else RoutePath(path, cost=self.name)
        self.start, self.end = window(self.name, start, end)

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
        """Offset vectors [..., 2] from the path and station [...] along it of points `xy` [..., 2]."""
        return offset_and_station(xy, *self.route.like(xy))


@GUIDANCE.register
class RouteCost(_RouteCost):
    """Drive along `path` (scene frame): agent `slot`'s squared distance to the polyline, averaged over the steps
    [start, end); beyond `cap` m it grows linearly (a Huber loss), so an agent far off the route is pulled
    without an exploding gradient."""

    name = "route"

    def __init__(
        self,
        slot: int,
        path: Sequence[Sequence[float]] | Tensor | RoutePath,
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
        path: Sequence[Sequence[float]] | Tensor | RoutePath,
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


@GUIDANCE.register
class LeadCost(GuidanceCost):
    """Progress along `path` relative to agent `other`: with `mode` "reach", agent `slot` is at least `lead` m
    further along it than `other` at every step of [start, end); with "hold", at most. Both are projected on the
    path (`other` may drive in a lane beside it); only `slot` is steered (`other`'s positions are taken as given). The
    cost is the mean squared shortfall or overshoot in metres; none where either agent is padding."""

    name = "lead"

    def __init__(
        self,
        slot: int,
        other: int,
        path: Sequence[Sequence[float]] | Tensor | RoutePath,
        lead: float,
        *,
        mode: Literal["reach", "hold"] = "reach",
        start: int = 0,
        end: int | None = None,
    ):
        self.slot, self.other = as_slot(self.name, slot), as_slot(self.name, other)
        if self.other == self.slot:
            raise InputError(f"{self.name}: other must be another agent than slot {self.slot}")
        if mode not in ("reach", "hold"):
            raise InputError(f"{self.name}: mode must be 'reach' or 'hold', got {mode!r}")
        self.slots = (self.slot,)
        self.route = path if isinstance(path, RoutePath) else RoutePath(path, cost=self.name)
        self.start, self.end = window(self.name, start, end)
        self.mode, self.lead = mode, float(lead)

    def __call__(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        check_states(self.name, states, scene)
        check_slots(self.name, (self.slot, self.other), states.shape[1])
        valid = bool(scene.agent_valid[self.slot]) and bool(scene.agent_valid[self.other])
        if not valid or self.start >= states.shape[2]:
            return states.sum(dim=(1, 2, 3)) * 0.0  # padding, or a window past the horizon: no cost, in the graph
        steps = slice(self.start, self.end)
        _, mine = offset_and_station(states[:, self.slot, steps, :2], *self.route.like(states))
        _, theirs = offset_and_station(states[:, self.other, steps, :2].detach(), *self.route.like(states))
        miss = self.lead - (mine - theirs) if self.mode == "reach" else (mine - theirs) - self.lead
        return (torch.relu(miss) ** 2).mean(-1)
