"""The built-in guidance costs (paper appendix 'Guidance Details', and the usual goal / speed / map costs).

Each cost returns one value per candidate [S] to minimise. Per-agent costs are averaged over time and
summed over the agents they cover, so an agent's gradient does not shrink as more agents are guided.
Agents that are not valid in the scene (padding) never contribute.

See docs/simulation.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Literal

import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.guidance.base import (
    GUIDANCE,
    GuidanceCost,
    as_slot,
    as_slots,
    check_slots,
    check_states,
    in_window,
    window,
)
from langtraj.guidance.disks import DiskLayout, close_steps
from langtraj.guidance.geometry import offset_to_segments
from langtraj.guidance.scene import GuidanceScene

_EPS = 1e-6  # inside square roots: keeps distances differentiable at 0


def _zero(states: Tensor) -> Tensor:
    """A zero cost [S] that is still part of the graph (so every cost can be differentiated)."""
    return states.sum(dim=(1, 2, 3)) * 0.0


def _finite(cost: str, value: float, what: str, minimum: float = 0.0) -> float:
    value = float(value)
    if not math.isfinite(value) or value < minimum:
        raise InputError(f"{cost}: {what} must be finite and >= {minimum}, got {value}")
    return value


@GUIDANCE.register
class CollisionCost(GuidanceCost):
    """Drive `adversary` into `target`: the mean over the horizon of their centre distance d(t).

    The paper writes J_coll = -sum_t d(t) and says minimising it encourages collisions; with the update
    x0 - alpha grad J that only holds for +sum_t d(t), so this cost is sum_t d(t) / T (the paper's
    objective up to its sign, divided by T so weights do not depend on the horizon). Only the adversary
    is steered: the target's states are detached. With `until_contact`, steps after the first contact
    (centre distance within the mean of the two widths) no longer count.
    """

    name = "collision"

    def __init__(self, adversary: int, target: int, *, until_contact: bool = False):
        self.adversary = as_slot(self.name, adversary, "adversary")
        self.target = as_slot(self.name, target, "target")
        if self.adversary == self.target:
            raise InputError(f"{self.name}: adversary and target must be different agents, both are slot {adversary}")
        self.until_contact = bool(until_contact)
        self.slots = (self.adversary,)

    def __call__(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        check_states(self.name, states, scene)
        check_slots(self.name, (self.adversary, self.target), states.shape[1])
        valid = scene.agent_valid
        if not (bool(valid[self.adversary]) and bool(valid[self.target])):
            return _zero(states)
        gap = states[:, self.adversary, :, :2] - states[:, self.target, :, :2].detach()
        distance = torch.sqrt((gap**2).sum(-1) + _EPS)  # [S, T]
        if self.until_contact:
            widths = scene.agent_size[[self.adversary, self.target], 1].to(states)
            contact = (distance.detach() <= widths.mean()).long()
            distance = distance * ((contact.cumsum(-1) - contact) == 0)
        return distance.sum(-1) / states.shape[2]


@GUIDANCE.register
class NoCollisionCost(GuidanceCost):
    """Keep agents apart: the paper's disk approximation (from TrafficSim).

    Each agent is `num_disks` disks of radius width / 2 spread along its length. For a pair (i, j) at a
    step, d is the least distance between their disk centres and J_pair = 1 - d / (r_i + r_j + buffer)
    when positive. Pairs are (i in `slots`, j in `others`), i != j, both valid (None: all valid agents);
    a pair costs sum_t J_pair / max(1, overlapping steps). The paper prints max(1, sum_t J_pair), which
    read literally costs every pair at least 1 and has no gradient below 1; we read the max(1, .) as the
    usual safe divisor, which keeps each pair's cost in [0, 1] (its mean overlap) and zero without overlap.

    `reduction` says how the pairs' costs add up: "mean" (the paper's) divides their sum by N^2, N the
    number of valid agents involved, so the cost of one overlapping pair shrinks as the scene grows; "sum"
    does not divide, so a weight is a weight per overlapping pair whatever the scene's size (what the
    simulation's realism guidance and a prompted agent's keep-clear term use).
    """

    name = "no_collision"
    scene_wide = True

    def __init__(
        self,
        slots: int | Iterable[int] | None = None,
        *,
        others: int | Iterable[int] | None = None,
        num_disks: int = 5,
        buffer: float = 0.0,
        reduction: Literal["mean", "sum"] = "mean",
    ):
        self.slots = as_slots(self.name, slots)
        self.others = as_slots(self.name, others, "others")
        if isinstance(num_disks, bool) or not isinstance(num_disks, int) or num_disks < 1:
            raise InputError(f"{self.name}: num_disks must be an integer >= 1, got {num_disks!r}")
        self.num_disks = num_disks
        self.buffer = _finite(self.name, buffer, "buffer")
        if reduction not in ("mean", "sum"):
            raise InputError(f"{self.name}: reduction must be 'mean' or 'sum', got {reduction!r}")
        self.reduction = reduction

    def __call__(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        steered = self.steered(states, scene)
        num_samples, num_agents = states.shape[:2]
        others = scene.agent_valid.to(states.device)
        if self.others is not None:
            check_slots(self.name, self.others, num_agents)
            chosen = torch.zeros_like(others)
            chosen[list(self.others)] = True
            others = others & chosen
        pairs = steered[:, None] & others[None, :] & ~torch.eye(num_agents, dtype=torch.bool, device=states.device)
        if not pairs.any():
            return _zero(states)
        layout = DiskLayout.of(scene, self.num_disks, states)
        # J_pair is symmetric: each unordered pair is computed once and counted as often as it is asked for.
        unordered = (pairs | pairs.T).triu(diagonal=1)
        first, second = unordered.nonzero(as_tuple=True)
        close = close_steps(states, layout, first, second, self.buffer)
        if close is None:
            return _zero(states)
        multiplicity = (pairs[close.first, close.second].to(states) + pairs[close.second, close.first].to(states))[None]
        num_pairs = close.first.shape[0]
        penalty = layout.penalty(close.state_i, close.state_j, close.i, close.j, self.buffer)
        row = close.sample * num_pairs + close.pair
        total = states.new_zeros(num_samples * num_pairs).index_add(0, row, penalty)
        overlapping = states.new_zeros(num_samples * num_pairs).index_add(0, row, (penalty.detach() > 0).to(states))
        per_pair = (total / overlapping.clamp(min=1.0)).view(num_samples, num_pairs)
        summed = (per_pair * multiplicity).sum(-1)
        if self.reduction == "sum":
            return summed
        return summed / int((steered | others).sum()) ** 2  # N: the valid agents involved


@GUIDANCE.register
class GoalCost(GuidanceCost):
    """Reach `goal` (x, y, scene frame): the distance of agent `slot`'s position at `step` (default the
    last step of the horizon) to it, in metres."""

    name = "goal"

    def __init__(self, slot: int, goal: Sequence[float], *, step: int | None = None):
        self.slot = as_slot(self.name, slot)
        values = [float(v) for v in goal]
        if len(values) != 2 or not all(math.isfinite(v) for v in values):
            raise InputError(f"{self.name}: goal must be two finite numbers (x, y), got {goal!r}")
        self.goal = tuple(values)
        if step is not None and step < 0:
            raise InputError(f"{self.name}: step must be >= 0, got {step}")
        self.step = step
        self.slots = (self.slot,)

    def __call__(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        if not self.steered(states, scene).any():
            return _zero(states)
        step = states.shape[2] - 1 if self.step is None else self.step
        if step >= states.shape[2]:
            raise InputError(f"{self.name}: step {step} is past the horizon of {states.shape[2]} steps")
        gap = states[:, self.slot, step, :2] - torch.tensor(self.goal, dtype=states.dtype, device=states.device)
        return torch.sqrt((gap**2).sum(-1) + _EPS)


@GUIDANCE.register
class TargetSpeedCost(GuidanceCost):
    """Drive at `speed` (m/s; one value, or one per slot): the mean squared speed error over the steps
    [start, end) of the horizon, summed over the slots."""

    name = "target_speed"

    def __init__(
        self, slots: int | Iterable[int], speed: float | Sequence[float], *, start: int = 0, end: int | None = None
    ):
        chosen = as_slots(self.name, slots)
        if chosen is None:
            raise InputError(f"{self.name}: slots must name at least one agent, got None")
        self.slots = chosen
        speeds = [speed] * len(chosen) if isinstance(speed, int | float) else list(speed)
        if len(speeds) != len(chosen):
            raise InputError(f"{self.name}: {len(speeds)} speeds for {len(chosen)} slots")
        self.speeds = tuple(_finite(self.name, v, "speed") for v in speeds)
        self.start, self.end = window(self.name, start, end)

    def __call__(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        check_states(self.name, states, scene)
        check_slots(self.name, self.slots or (), states.shape[1])
        index = torch.tensor(self.slots, device=states.device)
        valid = scene.agent_valid.to(states.device)[index]
        speed = in_window(self.name, states, self.start, self.end)[:, index, :, 3]
        target = torch.tensor(self.speeds, dtype=states.dtype, device=states.device)[None, :, None]
        return (((speed - target) ** 2).mean(-1) * valid).sum(-1)


@GUIDANCE.register
class OnRoadCost(GuidanceCost):
    """Stay on the road: penalise agent centres off the road or within `margin` m of a road edge.

    The signed distance to the nearest road-edge segment is positive on the edge's right (off the road:
    edges keep the road on their left, as in WOMD and WOSAC) and negative on its left; the cost is
    relu(signed + margin)^2, averaged over time and summed over the agents (None: all valid). A point's
    side follows its nearest segment only, so near a sharp corner of an edge the sign may be wrong over a
    small area. A scene without road edges costs nothing. A scene with a road field
    (`GuidanceScene.with_road_field`, what simulations use) samples the signed distance from it instead,
    exact where the nearest edge is straight and within centimetres elsewhere (`guidance.road_field`);
    points outside the field are searched exactly.
    """

    name = "on_road"
    scene_wide = True

    def __init__(self, slots: int | Iterable[int] | None = None, *, margin: float = 1.0):
        self.slots = as_slots(self.name, slots)
        self.margin = _finite(self.name, margin, "margin")

    def __call__(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        return self.per_agent(states, scene).sum(-1)

    def per_agent(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        """Each agent's share of the cost: [S, A], zero for agents it does not steer (what a selector
        that picks each agent's candidate on its own compares, `sim.selection.PerAgent`)."""
        steered = self.steered(states, scene)
        out = states.new_zeros(states.shape[:2])
        if scene.road_edges.shape[0] == 0 or not steered.any():
            return out + _zero(states)[:, None]
        xy = states[..., :2] if steered.all() else states[:, steered, :, :2]
        signed = signed_road_distance(xy, scene)
        past = torch.relu(signed + self.margin)
        cost = (past * past).mean(-1)  # [S, steered]
        return cost if steered.all() else out.index_add(1, steered.nonzero()[:, 0], cost)


def signed_road_distance(xy: Tensor, scene: GuidanceScene) -> Tensor:
    """Signed distance (m, positive off the road) of points xy [..., 2] to the road edges of `scene` (which has
    some): sampled from its road field where it has one, searched exactly elsewhere. Differentiable in `xy`."""
    edges = scene.road_edges.to(xy)
    if scene.road_field is None:
        return signed_edge_distance(xy, edges)
    signed, inside = scene.road_field.sample(xy)
    if not inside.all():
        signed = signed.masked_scatter(~inside, signed_edge_distance(xy[~inside], edges))
    return signed


def signed_edge_distance(xy: Tensor, edges: Tensor) -> Tensor:
    """Signed distance [...] of points `xy` [..., 2] to their nearest road-edge segment (`edges` [E, 2, 2],
    E > 0), searched exactly: positive on the segment's right (off the road), differentiable in `xy`."""
    offset, index = offset_to_segments(xy, edges[:, 0], edges[:, 1])
    start, end = edges[index, 0], edges[index, 1]
    direction, relative = end - start, xy.detach() - start
    left = direction[..., 0] * relative[..., 1] - direction[..., 1] * relative[..., 0] > 0
    distance = torch.sqrt((offset**2).sum(-1) + _EPS)
    return torch.where(left, -distance, distance)


@GUIDANCE.register
class KeepLaneCost(GuidanceCost):
    """Stay on a lane centre: the squared distance (m^2) to the nearest lane-centre segment, averaged over
    the steps [start, end) and summed over the agents (None: all valid). No lanes, no cost."""

    name = "keep_lane"
    scene_wide = True

    def __init__(self, slots: int | Iterable[int] | None = None, *, start: int = 0, end: int | None = None):
        self.slots = as_slots(self.name, slots)
        self.start, self.end = window(self.name, start, end)

    def __call__(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        steered = self.steered(states, scene)
        start, end = scene.lane_segments()
        if start.shape[0] == 0 or not steered.any():
            return _zero(states)
        xy = in_window(self.name, states, self.start, self.end)[:, steered, :, :2]
        offset, _ = offset_to_segments(xy, start.to(states), end.to(states))
        return (offset**2).sum(-1).mean(-1).sum(-1)


@GUIDANCE.register
class HeadwayCost(GuidanceCost):
    """Keep the agents in `slots` that follow `leader` behind it: for each that starts behind the leader and
    within its lane corridor (centres `corridor` m apart across the leader's heading, at the first planned step),
    the mean over the horizon of relu(1 - d(t) / need), d(t) the distance from its centre to the leader's along the
    leader's heading and need = `gap` + their half lengths. Unlike the disk costs, its gradient only ever pulls a
    follower back, so it slows down rather than overtaking through the leader. The leader's states are detached.
    Used to keep the simulated agents behind an ego under test (docs/testing.md, 'How the other agents react')."""

    name = "headway"

    def __init__(self, slots: int | Iterable[int], leader: int, *, gap: float = 2.0, corridor: float = 2.5):
        self.slots = as_slots(self.name, slots)
        self.leader = as_slot(self.name, leader, "leader")
        self.gap = _finite(self.name, gap, "gap")
        self.corridor = _finite(self.name, corridor, "corridor")

    def __call__(self, states: Tensor, scene: GuidanceScene) -> Tensor:
        check_states(self.name, states, scene)
        slots = [s for s in (self.slots or range(states.shape[1])) if s != self.leader]
        check_slots(self.name, (*slots, self.leader), states.shape[1])
        valid = scene.agent_valid
        slots = [s for s in slots if bool(valid[s])]
        if not slots or not bool(valid[self.leader]):
            return _zero(states)
        lead = states[:, self.leader].detach()  # [S, T, 4]
        mine = states[:, slots]  # [S, F, T, 4]
        ahead = torch.stack([torch.cos(lead[..., 2]), torch.sin(lead[..., 2])], -1)[:, None]  # [S, 1, T, 2]
        offset = lead[:, None, :, :2] - mine[..., :2]
        d = (offset * ahead).sum(-1)  # [S, F, T]: how far the leader is ahead
        across = (offset[..., 0] * ahead[..., 1] - offset[..., 1] * ahead[..., 0]).abs()
        follows = ((d[..., 0] > 0) & (across[..., 0] < self.corridor)).detach().to(states.dtype)  # [S, F]
        lengths = scene.agent_size[:, 0].to(states)
        need = self.gap + (lengths[slots] + lengths[self.leader]) / 2  # [F]
        short = torch.relu(1.0 - d / need[None, :, None])  # [S, F, T]
        return (short.mean(-1) * follows).sum(-1)
