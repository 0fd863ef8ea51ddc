"""The guidance terms a simulation request asks for, in model slots: collision guidance that drives an
adversary into a target, and the scene-wide costs `--guidance NAME=WEIGHT` names (docs/simulation.md)."""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping, Sequence

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


def pair_problem(
    adversary: int | str | None,
    target: int | str | None,
    *,
    sim_ids: Collection[int] | None = None,
    driven: Collection[int] | None = None,
    ego: int | str | None = None,
) -> tuple[str, str] | None:
    """What is wrong with an adversary and a target (track ids; `ego` the ego's, or "ego" before it is known) as a
    collision pair, as ("adversary" or "target", why), or None: the one rule `simulate`, the env, a suite and the
    studio apply. Both or neither; two agents; the adversary not the ego (which a planner drives); where the scene
    is known, both sim agents (`sim_ids`: valid at the current step) and, where the model's agents are, both driven
    (`driven`)."""
    if adversary is None and target is None:
        return None
    if adversary is None or target is None:
        return ("target" if target is None else "adversary", "an adversary needs a target and a target an adversary")
    if adversary == target:
        return "target", f"the adversary and the target are the same agent (@{adversary})"
    if ego is not None and adversary in (ego, "ego"):
        return "adversary", f"@{adversary} is the ego, which the planner drives; it cannot be the adversary"
    for role, track in (("adversary", adversary), ("target", target)):
        if sim_ids is not None and track not in sim_ids:
            shown = sorted(sim_ids)
            listed = f"{', '.join(str(i) for i in shown[:30])}{' ...' if len(shown) > 30 else ''}"
            return role, f"@{track} is not an agent of this scene at its current step; sim agents: {listed}"
        if driven is not None and track not in driven:
            return role, f"@{track} is not among the {len(driven)} agents the model drives"
    return None


def collision_terms(scenario: Scenario, slots: Mapping[int, int], request: SimRequest) -> list[GuidanceTerm]:
    """The collision term of `request.adversary` and `request.target` (track ids; `slots` maps the driven
    ones to model slots), or none when neither is given; a pair `pair_problem` refuses raises InputError."""
    adversary, target = request.adversary, request.target
    sim_ids = set(scenario.agents.ids[sim_agent_indices(scenario)].tolist())
    problem = pair_problem(adversary, target, sim_ids=sim_ids, driven=set(slots))
    if problem is not None:
        raise InputError(problem[1], where=f"--{problem[0]}")
    if adversary is None or target is None:
        return []
    if not math.isfinite(request.collision_weight) or request.collision_weight < 0:
        raise InputError(f"must be finite and >= 0, got {request.collision_weight}", where="--collision-weight")
    return [GuidanceTerm(CollisionCost(slots[adversary], slots[target]), request.collision_weight)]
