"""Candidate selection: which of the M joint candidates sampled at a replan each rollout executes.

The paper executes the candidate with the lowest collision cost (appendix 'Implementation Details');
with cost guidance the candidate that best meets the guidance objective is the natural choice, since
the lowest-collision one would undo collision guidance. Selectors are registered by name.

See docs/simulation.md.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from typing import ClassVar

import torch
from torch import Tensor

from langtraj.guidance import GuidanceScene, GuidanceTerm, NoCollisionCost, OnRoadCost
from langtraj.guidance.disks import candidate_overlaps
from langtraj.registry import Registry


class CandidateSelector(ABC):
    """Picks a candidate per rollout, or per rollout and agent, from states [M, R, A, T, 4] (scene frame,
    the planning horizon)."""

    name: ClassVar[str]
    uses_road: ClassVar[bool] = False
    """Whether it compares candidates by the on-road cost (a simulation then gives its scene a road field)."""

    @abstractmethod
    def select(
        self, states: Tensor, scene: GuidanceScene, terms: Sequence[GuidanceTerm], first: Tensor | None = None
    ) -> Tensor:
        """Index of the chosen candidate of each rollout, long [R] (a joint choice), or of each agent of
        each rollout, long [R, A] (agents assembled from different candidates). `first` [M, R, A] (lower is
        better, zero for agents it does not concern) is compared before anything else: how far each agent's
        candidate is from doing what its prompt asks (`sim.adherence`)."""


def chosen_states(states: Tensor, choice: Tensor) -> Tensor:
    """The executed states [R, A, T, 4] of candidates [M, R, A, T, 4] by a selector's `choice` ([R] or [R, A])."""
    r, a = states.shape[1:3]
    if choice.dim() == 1:
        choice = choice[:, None].expand(r, a)
    rows = torch.arange(r, device=states.device)[:, None]
    return states[choice, rows, torch.arange(a, device=states.device)[None, :]]


SELECTORS: Registry[CandidateSelector] = Registry("candidate selector")


FIRST_WEIGHT = 1e4
"""Scale of `first` against the other criteria: any difference in it outweighs them."""


def _joint_first(first: Tensor | None) -> Tensor | float:
    """`first` of joint candidates [M, R] (summed over the agents), scaled to come before anything else (0
    without it)."""
    return 0.0 if first is None else FIRST_WEIGHT * first.sum(-1)


def _per_candidate(cost, states: Tensor, scene: GuidanceScene) -> Tensor:
    """A cost [M * R] of candidates flattened sample-major, reshaped to [M, R]."""
    m, r = states.shape[:2]
    return cost(states.reshape(m * r, *states.shape[2:]), scene).reshape(m, r)


@SELECTORS.register
class MinCollision(CandidateSelector):
    """The candidate with the least disk overlap between the driven agents (the paper's default)."""

    name = "min_collision"

    def select(
        self, states: Tensor, scene: GuidanceScene, terms: Sequence[GuidanceTerm], first: Tensor | None = None
    ) -> Tensor:
        with torch.no_grad():
            return (_joint_first(first) + _per_candidate(NoCollisionCost(), states, scene)).argmin(dim=0)


@SELECTORS.register
class MinCollisionOffroad(CandidateSelector):
    """The paper's selection with map adherence added: the least disk overlap plus the on-road cost
    (squared distance of the driven agents' centres past the road edge, 1 m margin, `OnRoadCost`)."""

    name = "min_collision_offroad"
    uses_road = True

    def select(
        self, states: Tensor, scene: GuidanceScene, terms: Sequence[GuidanceTerm], first: Tensor | None = None
    ) -> Tensor:
        with torch.no_grad():
            cost = _per_candidate(NoCollisionCost(), states, scene) + _per_candidate(OnRoadCost(), states, scene)
            return (_joint_first(first) + cost).argmin(dim=0)


@SELECTORS.register
class PerAgent(CandidateSelector):
    """Each agent its own candidate: starting from the paper's joint choice (`min_collision`), every agent
    in slot order (most important first) takes the candidate with the least on-road cost (`OnRoadCost`,
    its own share) plus `collision_weight` x its disk overlap with the others as assembled so far; ties
    keep the joint choice. Agents no longer share one joint sample, but the overlap term keeps the
    assembled scene apart (docs/simulation.md, 'Candidate selection').

    The overlaps of every two agents' candidates are tabulated once (`guidance.disks.candidate_overlaps`,
    the pair terms of `NoCollisionCost`), so both the joint choice and each agent's step read the table."""

    name = "per_agent"
    uses_road = True
    collision_weight = 10.0  # an agent's summed pair overlaps (each in [0, 1]) against m^2 of road cost

    def select(
        self, states: Tensor, scene: GuidanceScene, terms: Sequence[GuidanceTerm], first: Tensor | None = None
    ) -> Tensor:
        m, r, a = states.shape[:3]
        with torch.no_grad():
            overlaps = candidate_overlaps(states, scene)
            lead, follow, table = overlaps.first, overlaps.second, overlaps.table  # table [R, Q, M, M]
            # The joint choice: NoCollisionCost of each joint candidate is its pairs' diagonal entries.
            joint = table.diagonal(dim1=2, dim2=3).sum(1)  # [R, M]
            if first is not None:
                joint = joint + _joint_first(first).T
            choice = joint.argmin(dim=1)[:, None].expand(r, a).clone()
            road = OnRoadCost().per_agent(states.reshape(m * r, *states.shape[2:]), scene).reshape(m, r, a)
            rows = torch.arange(r, device=states.device)
            for agent in scene.agent_valid.nonzero()[:, 0].tolist():
                as_first, as_second = (lead == agent).nonzero()[:, 0], (follow == agent).nonzero()[:, 0]
                # This agent's overlap per own candidate [R, M] with the others at their current choice.
                overlap = table[rows[:, None], as_first[None], :, choice[:, follow[as_first]]].sum(1)
                overlap = overlap + table[rows[:, None], as_second[None], choice[:, lead[as_second]], :].sum(1)
                cost = road[:, :, agent] + self.collision_weight * overlap.T
                if first is not None:
                    cost = cost + FIRST_WEIGHT * first[:, :, agent]
                cost = cost + 1e-6 * (torch.arange(m, device=states.device)[:, None] != choice[None, :, agent])
                choice[:, agent] = cost.argmin(dim=0)
            return choice


@SELECTORS.register
class MinGuidance(CandidateSelector):
    """The candidate with the lowest weighted sum of the guidance costs (falls back to min_collision
    when there is no guidance term)."""

    name = "min_guidance"

    def select(
        self, states: Tensor, scene: GuidanceScene, terms: Sequence[GuidanceTerm], first: Tensor | None = None
    ) -> Tensor:
        if not terms:
            return MinCollision().select(states, scene, terms, first)
        with torch.no_grad():
            total = sum(term.weight * _per_candidate(term.cost, states, scene) for term in terms)
            return (_joint_first(first) + total).argmin(dim=0)


@SELECTORS.register
class FirstCandidate(CandidateSelector):
    """Candidate 0: plain sampling, no selection; with `first`, the joint candidate least short of what the prompts
    ask (the least `first` summed over the agents), candidate 0 among equals."""

    name = "first"

    def select(
        self, states: Tensor, scene: GuidanceScene, terms: Sequence[GuidanceTerm], first: Tensor | None = None
    ) -> Tensor:
        if first is None:
            return torch.zeros(states.shape[1], dtype=torch.long, device=states.device)
        with torch.no_grad():
            return _joint_first(first).argmin(dim=0)  # argmin takes the first of equal minima
