"""Feasibility: whether an agent can do a behaviour from where it is, which is whether the map gives it a target
(`derive.target_of`); the reason is the target's. One search answers both, so a behaviour called feasible
always has a target to steer toward (docs/interdrive.md, 'Targets and feasibility')."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from langtraj.errors import InputError
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour
from langtraj.interdrive.targets.config import CounterfactualConfig
from langtraj.interdrive.targets.context import TargetContext
from langtraj.interdrive.targets.derive import stop_after, target_of
from langtraj.interdrive.targets.target import BehaviourTarget, Status, TargetUnavailable
from langtraj.roads import MapIndex
from langtraj.scenario.model import Scenario


@dataclass(frozen=True)
class Feasibility:
    """Whether agent `track_id` can do `behaviour` here (`status`), why not (`reason`), and the `target` it
    steers toward when it can."""

    track_id: int
    behaviour: Behaviour
    status: Status
    reason: str = ""
    target: BehaviourTarget | None = None
    other_id: int | None = None
    """The other agent of a pair behaviour."""

    @property
    def message(self) -> str:
        """The line a warning prints, "@12 cannot turn left: ...", "@12 cannot cut in front of @7: ..." (empty when
        feasible)."""
        if self.status == "feasible":
            return ""
        other = f" @{self.other_id}" if self.other_id is not None else ""
        return f"@{self.track_id} cannot {BEHAVIOURS[self.behaviour].manoeuvre}{other}: {self.reason}"


def feasibility(
    scenario: Scenario,
    track_id: int,
    behaviour: Behaviour,
    index: MapIndex,
    *,
    other_id: int | None = None,
    config: CounterfactualConfig | None = None,
    gap: float | None = None,
    deceleration: float | None = None,
    context: TargetContext | None = None,
    routes: Mapping[int, np.ndarray] | None = None,
) -> Feasibility:
    """Whether `track_id` can do `behaviour` (toward `other_id` for a pair behaviour; a cut-in `gap` m ahead of it; a
    braking lead at `deceleration` m/s^2) at the current step: feasible with its target, or infeasible / undecided
    with the reason the map gives no target. `context`: the scene's map as read for earlier questions (its agents'
    lanes, junctions and roads ahead, each found once), for a caller asking many; `routes`: the agents' known routes
    (`TargetContext`), where no `context` is given."""
    context = context if context is not None else TargetContext(scenario, index, config, routes)
    return _verdict(context, track_id, behaviour, other_id, gap, deceleration)


def behaviour_feasibility(
    scenario: Scenario, track_id: int, map_index: MapIndex, config: CounterfactualConfig | None = None
) -> dict[Behaviour, Feasibility]:
    """`feasibility` of every single-agent behaviour for `track_id`, the map read once for them all. Pair behaviours
    are decided per other agent (`feasibility` with `other_id`); which pairs to ask about comes from the interactions
    the log shows (`counterfactual.feasible_alternatives`)."""
    context = TargetContext(scenario, map_index, config)
    return {b: _verdict(context, track_id, b, None) for b, spec in BEHAVIOURS.items() if not spec.is_pair}


def _verdict(
    context: TargetContext,
    track_id: int,
    behaviour: Behaviour,
    other_id: int | None,
    gap: float | None = None,
    deceleration: float | None = None,
) -> Feasibility:
    """The target `context` gives, as a verdict."""
    try:
        target = target_of(context, track_id, behaviour, other_id, gap, deceleration)
    except TargetUnavailable as exc:
        return Feasibility(track_id, behaviour, exc.status, exc.reason, other_id=other_id)
    return Feasibility(track_id, behaviour, "feasible", target=target, other_id=other_id)


def then_feasibility(verdict: Feasibility, then: Behaviour) -> Feasibility:
    """The verdict on a manoeuvre and then `then` (a stop: `derive.stop_after`): feasible with the two in one target
    where the manoeuvre is and the map has room for what follows it; else the manoeuvre's own refusal, or why what
    follows has no room ("... then stop: a stop past its turn (40 m ahead) is beyond its reach in 7 s")."""
    if verdict.target is None:
        return verdict
    if then is not Behaviour.STOP:
        raise InputError(
            f"{then.value} after {verdict.behaviour.value} is not a sequence LangTraj steers", where="then"
        )
    try:
        return replace(verdict, target=stop_after(verdict.target))
    except TargetUnavailable as exc:
        return Feasibility(
            verdict.track_id,
            verdict.behaviour,
            exc.status,
            f"then {then.value}: {exc.reason}",
            other_id=verdict.other_id,
        )
