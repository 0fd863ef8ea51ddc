"""Feasibility: whether an agent can do a behaviour from where it is, which is whether the map gives it a target
(`derive.derive_target`); the reason is the target's. One search answers both, so a behaviour called feasible
always has a target to steer toward (docs/interdrive.md, 'Targets and feasibility')."""

from __future__ import annotations

from dataclasses import dataclass

from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour
from langtraj.interdrive.mapindex import MapIndex
from langtraj.interdrive.targets.config import CounterfactualConfig
from langtraj.interdrive.targets.derive import BehaviourTarget, Status, TargetUnavailable, derive_target
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

    @property
    def message(self) -> str:
        """The line a warning prints, "@12 cannot turn left: ..." (empty when feasible)."""
        if self.status == "feasible":
            return ""
        return f"@{self.track_id} cannot {BEHAVIOURS[self.behaviour].manoeuvre}: {self.reason}"


def feasibility(
    scenario: Scenario,
    track_id: int,
    behaviour: Behaviour,
    index: MapIndex,
    *,
    other_id: int | None = None,
    config: CounterfactualConfig | None = None,
) -> Feasibility:
    """Whether `track_id` can do `behaviour` (toward `other_id` for a pair behaviour) at the current step: feasible
    with its target, or infeasible / undecided with the reason the map gives no target."""
    try:
        target = derive_target(scenario, track_id, behaviour, index, other_id=other_id, config=config)
    except TargetUnavailable as exc:
        return Feasibility(track_id, behaviour, exc.status, exc.reason)
    return Feasibility(track_id, behaviour, "feasible", target=target)


def behaviour_feasibility(
    scenario: Scenario, track_id: int, map_index: MapIndex, config: CounterfactualConfig | None = None
) -> dict[Behaviour, Feasibility]:
    """`feasibility` of every single-agent behaviour for `track_id`. Pair behaviours are decided per other agent
    (`feasibility` with `other_id`); which pairs to ask about comes from the interactions the log shows
    (`counterfactual.feasible_alternatives`)."""
    config = config or CounterfactualConfig()
    return {
        b: feasibility(scenario, track_id, b, map_index, config=config)
        for b, spec in BEHAVIOURS.items()
        if not spec.is_pair
    }
