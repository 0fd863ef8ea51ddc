"""The guidance terms a simulation request asks for, in model slots: collision guidance that drives an
adversary into a target, and the scene-wide costs `--guidance NAME=WEIGHT` names (docs/simulation.md)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from langtraj.errors import InputError
from langtraj.guidance import GUIDANCE, CollisionCost, GuidanceCost, GuidanceTerm
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.scenario.model import Scenario
from langtraj.sim.config import SimRequest


def scene_wide_costs() -> dict[str, type[GuidanceCost]]:
    """The registered costs that take no parameters and steer every driven agent (`scene_wide`), by name:
    what `--guidance` accepts."""
    return {cls.name: cls for cls in GUIDANCE.classes() if cls.scene_wide}


def scene_wide_terms(items: Sequence[str]) -> list[GuidanceTerm]:
    """Terms of `NAME=WEIGHT` items, each a scene-wide cost with a finite weight >= 0."""
    known = scene_wide_costs()
    terms = []
    for item in items:
        name, sep, weight_text = item.partition("=")
        if not sep:
            raise InputError(f"expected NAME=WEIGHT, got {item!r}", where="--guidance")
        if name not in known:
            raise InputError(
                f"{name!r} cannot be given here; known: {', '.join(known)} (the other costs need agents or values: "
                "use --adversary/--target, or langtraj.guidance in Python)",
                where="--guidance",
            )
        try:
            weight = float(weight_text)
        except ValueError:
            raise InputError(f"weight of {name} is not a number: {weight_text!r}", where="--guidance") from None
        if not math.isfinite(weight) or weight < 0:
            raise InputError(f"weight of {name} must be finite and >= 0, got {weight_text}", where="--guidance")
        terms.append(GuidanceTerm(known[name](), weight))
    return terms


def collision_terms(scenario: Scenario, slots: Mapping[int, int], request: SimRequest) -> list[GuidanceTerm]:
    """The collision term of `request.adversary` and `request.target` (track ids; `slots` maps the driven
    ones to model slots), or none when neither is given."""
    adversary, target = request.adversary, request.target
    if adversary is None and target is None:
        return []
    if adversary is None or target is None:
        raise InputError("--adversary and --target go together", where="arguments")
    if adversary == target:
        raise InputError(f"the adversary and the target are the same agent (@{adversary})", where="--target")
    sim_ids = set(scenario.agents.ids[sim_agent_indices(scenario)].tolist())
    for flag, track in (("--adversary", adversary), ("--target", target)):
        if track not in sim_ids:
            raise InputError(
                f"@{track} is not an agent of this scene at its current step; sim agents: "
                f"{', '.join(str(i) for i in sorted(sim_ids)[:30])}{' ...' if len(sim_ids) > 30 else ''}",
                where=flag,
            )
        if track not in slots:
            raise InputError(f"@{track} is not among the {len(slots)} agents the model drives", where=flag)
    if not math.isfinite(request.collision_weight) or request.collision_weight < 0:
        raise InputError(f"must be finite and >= 0, got {request.collision_weight}", where="--collision-weight")
    return [GuidanceTerm(CollisionCost(slots[adversary], slots[target]), request.collision_weight)]
