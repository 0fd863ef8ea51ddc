"""Agents as disks (paper appendix 'Non-Collision Guidance', after TrafficSim): their layout, the overlap
penalty of two agents at a step, and the search for the steps at which two paths come close enough for
their disks to overlap.

`NoCollisionCost` sums these penalties over the pairs of one joint sample; `candidate_overlaps`
tabulates them for every combination of two agents' candidates at once, which is what a selector that
assembles each agent's candidate on its own (`sim.selection.PerAgent`) compares. See
docs/simulation.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

from langtraj.guidance.geometry import CHUNK_ELEMENTS
from langtraj.guidance.scene import GuidanceScene

WINDOW = 8
"""Steps per window of the coarse search: paths whose boxes over a window never come close are skipped."""
_EPS = 1e-6  # inside square roots: keeps distances differentiable at 0


@dataclass(frozen=True)
class DiskLayout:
    """Each agent as `num_disks` disks of radius width / 2 spread along its length: `radius` [A], the
    farthest disk centre from the agent's centre `reach` [A], and the centres' offsets along its heading
    `offsets` [A, D]."""

    radius: Tensor
    reach: Tensor
    offsets: Tensor

    @classmethod
    def of(cls, scene: GuidanceScene, num_disks: int, like: Tensor) -> DiskLayout:
        """The layout of the scene's agents, as `like`'s dtype and device."""
        size = scene.agent_size.to(like)
        radius = (size[:, 1] / 2).clamp(min=1e-3)
        reach = (size[:, 0] / 2 - radius).clamp(min=0.0)
        offsets = torch.linspace(-1.0, 1.0, num_disks, device=like.device, dtype=like.dtype) * reach[:, None]
        if num_disks == 1:
            offsets = torch.zeros_like(offsets)
        return cls(radius=radius, reach=reach, offsets=offsets)

    def limit(self, i: Tensor, j: Tensor, buffer: float) -> Tensor:
        """The centre distance below which agents i and j (long [Q]) can overlap: beyond it, no disk does."""
        return self.reach[i] + self.radius[i] + self.reach[j] + self.radius[j] + buffer

    def may_overlap(self, state_i: Tensor, state_j: Tensor, i: Tensor, j: Tensor, buffer: float) -> Tensor:
        """bool [K]: False where agents i, j (long [K]) at states [K, 4] cannot overlap (`penalty` is 0).

        Every disk centre lies on the agent's spine (its centre +- `reach` along its heading). Seen from
        agent i, a point of j's spine lies at least |dn| - reach_j |sin| across i's heading and
        |dh| - reach_i - reach_j |cos| along it (dn, dh: j's centre across and along, cos, sin: of the
        heading difference), so the nearest two centres are at least the norm of those two bounds apart."""
        gap = state_j[:, :2] - state_i[:, :2]
        heading = state_j[:, 2] - state_i[:, 2]
        forward = torch.stack([torch.cos(state_i[:, 2]), torch.sin(state_i[:, 2])], -1)
        along = (gap * forward).sum(-1)
        across = gap[:, 1] * forward[:, 0] - gap[:, 0] * forward[:, 1]
        lateral = (across.abs() - self.reach[j] * torch.sin(heading).abs()).clamp(min=0.0)
        longitudinal = (along.abs() - self.reach[i] - self.reach[j] * torch.cos(heading).abs()).clamp(min=0.0)
        return lateral**2 + longitudinal**2 < (self.radius[i] + self.radius[j] + buffer + 1e-4) ** 2

    def penalty(self, state_i: Tensor, state_j: Tensor, i: Tensor, j: Tensor, buffer: float) -> Tensor:
        """J_pair = relu(1 - d / (r_i + r_j + buffer)) [K] of agents i, j (long [K]) at states [K, 4], d the
        least distance between their disk centres; differentiable in both states.

        With g the gap between the centres, h the unit headings and o the disks' offsets, the squared
        distance between disk k of i and disk l of j is |g|^2 + o_k^2 + o_l^2 + 2 o_k g.h_i - 2 o_l g.h_j
        - 2 o_k o_l h_i.h_j: four numbers per pair instead of D x D difference vectors."""
        gap = state_i[:, :2] - state_j[:, :2]
        heading_i = torch.stack([torch.cos(state_i[:, 2]), torch.sin(state_i[:, 2])], -1)
        heading_j = torch.stack([torch.cos(state_j[:, 2]), torch.sin(state_j[:, 2])], -1)
        along_i, along_j = (gap * heading_i).sum(-1, keepdim=True), (gap * heading_j).sum(-1, keepdim=True)
        offsets_i, offsets_j = self.offsets[i], self.offsets[j]  # [K, D]
        square = (
            (gap * gap).sum(-1)[:, None, None]
            + (offsets_i * (offsets_i + 2 * along_i))[:, :, None]
            + (offsets_j * (offsets_j - 2 * along_j))[:, None, :]
            - 2 * (heading_i * heading_j).sum(-1)[:, None, None] * offsets_i[:, :, None] * offsets_j[:, None, :]
        )
        distance = torch.sqrt(square.flatten(1).min(-1).values.clamp(min=0.0) + _EPS)
        return torch.relu(1.0 - distance / (self.radius[i] + self.radius[j] + buffer))


def window_boxes(xy: Tensor) -> tuple[Tensor, Tensor]:
    """Bounding boxes of paths `xy` [..., T, 2] over windows of `WINDOW` steps: low, high [..., W, 2] (the
    last window padded with the last position)."""
    steps = xy.shape[-2]
    windows = -(-steps // WINDOW)
    pad = xy[..., -1:, :].expand(*xy.shape[:-2], windows * WINDOW - steps, 2)
    boxes = torch.cat([xy, pad], dim=-2).reshape(*xy.shape[:-2], windows, WINDOW, 2)
    return boxes.amin(dim=-2), boxes.amax(dim=-2)


def box_gap(low_a: Tensor, high_a: Tensor, low_b: Tensor, high_b: Tensor) -> Tensor:
    """Least distance between axis-aligned boxes (0 where they meet), over the last dimension (x, y)."""
    gap = torch.maximum(low_b - high_a, low_a - high_b).clamp(min=0.0)
    return torch.linalg.vector_norm(gap, dim=-1)


def near_pairs(low: Tensor, high: Tensor, first: Tensor, second: Tensor, limit: Tensor) -> Tensor:
    """bool [Q]: the pairs (first[q], second[q]) whose boxes over every row and window of `low`, `high`
    ([..., A, W, 2], the agent dimension third from last) come within `limit` [Q]; no other pair can
    overlap anywhere."""
    rows = tuple(range(low.ndim - 3)) + (low.ndim - 2,)
    all_low, all_high = low.amin(dim=rows), high.amax(dim=rows)  # [A, 2]
    return box_gap(all_low[first], all_high[first], all_low[second], all_high[second]) <= limit


def window_steps(window: Tensor, num_steps: int, *others: Tensor) -> tuple[Tensor, ...]:
    """The steps of each window index (long [H]) below `num_steps`, with `others` (long [H]) repeated
    alongside: (steps [H'], *others [H'])."""
    offsets = torch.arange(WINDOW, device=window.device)
    steps = (window[:, None] * WINDOW + offsets).flatten()
    keep = steps < num_steps
    return (steps[keep], *(o.repeat_interleave(WINDOW)[keep] for o in others))


@dataclass(frozen=True)
class CloseSteps:
    """The (sample, step, pair) triples at which two agents' disks can overlap (`close_steps`): the pairs
    `first[q]`, `second[q]` (long [Q]) whose paths come close anywhere, and per triple its `sample`, `step`,
    `pair` q, agents `i`, `j` and their states `state_i`, `state_j` [K, 4] (differentiable in the states)."""

    first: Tensor
    second: Tensor
    sample: Tensor
    step: Tensor
    pair: Tensor
    i: Tensor
    j: Tensor
    state_i: Tensor
    state_j: Tensor


def close_steps(states: Tensor, layout: DiskLayout, first: Tensor, second: Tensor, buffer: float) -> CloseSteps | None:
    """Where the pairs (first, second) of states [S, A, T, 4] can overlap, or None where they never do.

    Among the pairs whose boxes over all samples and steps come close enough (most pairs of a large scene never
    do), the steps of the windows in which the two paths' boxes do (found without autograd, in chunks of pairs),
    then of those the steps at which the disks can overlap (`DiskLayout.may_overlap`): only these get disk
    distances (`NoCollisionCost`, `guidance.projection`)."""
    num_samples, num_agents, num_steps, _ = states.shape
    xy = states[..., :2].detach()
    low, high = window_boxes(xy)  # [S, A, W, 2]
    near = near_pairs(low, high, first, second, layout.limit(first, second, buffer))
    first, second = first[near], second[near]
    if first.numel() == 0:
        return None
    limit = layout.limit(first, second, buffer)
    found = []
    chunk = max(1, CHUNK_ELEMENTS // (num_samples * low.shape[2] * 2))
    with torch.no_grad():
        for lo in range(0, len(first), chunk):
            i, j = first[lo : lo + chunk], second[lo : lo + chunk]
            gap = box_gap(low[:, i], high[:, i], low[:, j], high[:, j])
            s, q, w = (gap <= limit[lo : lo + chunk, None]).nonzero(as_tuple=True)
            found.append(window_steps(w, num_steps, s, q + lo))
    t, s, q = (torch.cat(parts) for parts in zip(*found, strict=True))
    i, j = first[q], second[q]
    flat = states.reshape(-1, states.shape[-1])
    state_i = flat.index_select(0, (s * num_agents + i) * num_steps + t)
    state_j = flat.index_select(0, (s * num_agents + j) * num_steps + t)
    with torch.no_grad():
        close = layout.may_overlap(state_i, state_j, i, j, buffer).nonzero()[:, 0]
    if close.numel() == 0:
        return None
    return CloseSteps(
        first=first,
        second=second,
        sample=s[close],
        step=t[close],
        pair=q[close],
        i=i[close],
        j=j[close],
        state_i=state_i[close],
        state_j=state_j[close],
    )


@dataclass(frozen=True)
class CandidateOverlaps:
    """J_pair for every combination of two agents' candidates: the unordered agent pairs `first[q] <
    second[q]` (long [Q]) whose paths come close in some combination, and `table[r, q, m_first,
    m_second]` [R, Q, M, M], each pair's overlap penalty averaged over its overlapping steps (as
    `NoCollisionCost` counts a pair) with `first` at its candidate m_first and `second` at m_second of
    rollout r. Pairs left out never overlap."""

    first: Tensor
    second: Tensor
    table: Tensor


@torch.no_grad()
def candidate_overlaps(
    states: Tensor, scene: GuidanceScene, *, num_disks: int = 5, buffer: float = 0.0
) -> CandidateOverlaps:
    """The overlaps of candidates states [M, R, A, T, 4] (M candidates of R rollouts) between every two
    valid agents of `scene`: pairs whose boxes over everything never come close are skipped, then those
    whose boxes over all candidates in a window do not, then window by window the combinations of
    candidates whose boxes do, then the steps at which their disks can overlap (`DiskLayout.may_overlap`)."""
    m, r, a, t, _ = states.shape
    device = states.device
    layout = DiskLayout.of(scene, num_disks, states)
    valid = scene.agent_valid.to(device)
    first, second = (torch.triu(valid[:, None] & valid[None, :], diagonal=1)).nonzero(as_tuple=True)
    xy = states[..., :2]
    low, high = window_boxes(xy)  # [M, R, A, W, 2]
    near = near_pairs(low, high, first, second, layout.limit(first, second, buffer))
    first, second = first[near], second[near]
    any_low, any_high = low.amin(0), high.amax(0)  # [R, A, W, 2]: over every candidate
    limit = layout.limit(first, second, buffer)

    # Pairs (and rollouts, windows) whose boxes over every candidate come close.
    hits = []
    windows = low.shape[3]
    chunk = max(1, CHUNK_ELEMENTS // (r * windows * 4))
    for lo in range(0, len(first), chunk):
        i, j = first[lo : lo + chunk], second[lo : lo + chunk]
        gap = box_gap(any_low[:, i], any_high[:, i], any_low[:, j], any_high[:, j])  # [R, q, W]
        rr, q, w = (gap <= limit[lo : lo + chunk, None]).nonzero(as_tuple=True)
        hits.append((rr, q + lo, w))
    rr, q, w = (torch.cat(p) for p in zip(*hits, strict=True)) if hits else (first[:0],) * 3
    kept = torch.unique(q)
    remap = torch.full((len(first),), -1, dtype=torch.long, device=device)
    remap[kept] = torch.arange(len(kept), device=device)
    table_sum = states.new_zeros(r, len(kept), m, m)
    table_count = states.new_zeros(r, len(kept), m, m)

    flat = states.reshape(-1, states.shape[-1])
    combos = torch.cartesian_prod(torch.arange(m, device=device), torch.arange(m, device=device))  # [M*M, 2]
    step = max(1, CHUNK_ELEMENTS // (len(combos) * WINDOW * 8))
    for lo in range(0, len(q), step):
        h_r, h_q, h_w = rr[lo : lo + step], q[lo : lo + step], w[lo : lo + step]
        i, j = first[h_q], second[h_q]
        # The candidate combinations whose boxes in this window come close.
        gap = box_gap(
            low[:, h_r, i, h_w][combos[:, 0]],
            high[:, h_r, i, h_w][combos[:, 0]],
            low[:, h_r, j, h_w][combos[:, 1]],
            high[:, h_r, j, h_w][combos[:, 1]],
        )  # [M*M, H]
        c, h = (gap <= limit[h_q][None]).nonzero(as_tuple=True)
        steps, c, h = window_steps(h_w[h], t, c, h)
        mi, mj, rows, qq = combos[c, 0], combos[c, 1], h_r[h], h_q[h]
        pi, pj = first[qq], second[qq]
        state_i = flat.index_select(0, ((mi * r + rows) * a + pi) * t + steps)
        state_j = flat.index_select(0, ((mj * r + rows) * a + pj) * t + steps)
        close = layout.may_overlap(state_i, state_j, pi, pj, buffer)
        mi, mj, rows, qq, pi, pj = (x[close] for x in (mi, mj, rows, qq, pi, pj))
        penalty = layout.penalty(state_i[close], state_j[close], pi, pj, buffer)
        cell = ((rows * len(kept) + remap[qq]) * m + mi) * m + mj
        table_sum.view(-1).index_add_(0, cell, penalty)
        table_count.view(-1).index_add_(0, cell, (penalty > 0).to(penalty))
    return CandidateOverlaps(first=first[kept], second=second[kept], table=table_sum / table_count.clamp(min=1.0))
