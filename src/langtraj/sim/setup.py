"""From what a user asks for (policy, checkpoint, prompts, adversary and target, guidance) to a checked
policy: bad input is found here, or (a prompt naming an agent the model does not drive) when the
policy is reset at the start of the simulation; either way before any file is written."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from langtraj.errors import InputError
from langtraj.guidance import CollisionCost, GuidanceTerm, KeepLaneCost, NoCollisionCost, OnRoadCost
from langtraj.interdrive.dataset import PromptEntry
from langtraj.model.open_loop import user_prompt_entry
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.scenario.model import Scenario
from langtraj.scenario.selection import prioritized_agents
from langtraj.sim.checkpoints import shipped_checkpoint
from langtraj.sim.policies import POLICIES, LangTrajPolicy, Policy

if TYPE_CHECKING:
    from langtraj.training.module import LangTrajModule

SCENE_WIDE_COSTS = {"no_collision": NoCollisionCost, "on_road": OnRoadCost, "keep_lane": KeepLaneCost}
"""Guidance costs `--guidance NAME=WEIGHT` applies to every driven agent (the others need parameters:
agents, a goal or a speed, and are built with `langtraj.guidance` in Python)."""


@dataclass(frozen=True)
class SimRequest:
    """A simulation as the command line states it (track ids, not model slots)."""

    policy: str = "langtraj"
    checkpoint: Path | None = None  # None: the shipped checkpoint
    prompts: tuple[str, ...] = ()
    adversary: int | None = None
    target: int | None = None
    collision_weight: float = 1.0
    guidance: tuple[str, ...] = ()  # "NAME=WEIGHT"
    guidance_scale: float = 1.0
    cfg: float = 0.0
    candidates: int = 4
    steps: int = 5


def merged_prompt(scenario: Scenario, prompts: tuple[str, ...]) -> PromptEntry | None:
    """One prompt entry from several typed prompts; an agent named by two prompts is an error."""
    entries = [user_prompt_entry(scenario, text) for text in prompts]
    if not entries:
        return None
    roles: dict[int, str] = {}
    for entry in entries:
        for track in entry.mentions:
            if track in roles:
                raise InputError(f"agent @{track} is named by two prompts; describe it in one", where="prompt")
            roles[track] = entry.roles[track]
    mentions = tuple(roles)
    return PromptEntry("; ".join(e.text for e in entries), mentions, roles, None, (), "user")


def _guidance_terms(items: tuple[str, ...]) -> list[GuidanceTerm]:
    terms = []
    for item in items:
        name, sep, weight_text = item.partition("=")
        if not sep:
            raise InputError(f"expected NAME=WEIGHT, got {item!r}", where="--guidance")
        if name not in SCENE_WIDE_COSTS:
            raise InputError(
                f"{name!r} cannot be given here; known: {', '.join(SCENE_WIDE_COSTS)} (goal, target_speed and "
                "collision need agents or values: use --adversary/--target, or langtraj.guidance in Python)",
                where="--guidance",
            )
        try:
            weight = float(weight_text)
        except ValueError:
            raise InputError(f"weight of {name} is not a number: {weight_text!r}", where="--guidance") from None
        if not math.isfinite(weight) or weight < 0:
            raise InputError(f"weight of {name} must be finite and >= 0, got {weight_text}", where="--guidance")
        terms.append(GuidanceTerm(SCENE_WIDE_COSTS[name](), weight))
    return terms


def _collision_term(scenario: Scenario, slots: dict[int, int], request: SimRequest) -> list[GuidanceTerm]:
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


def build_policy(
    scenario: Scenario, request: SimRequest, module: LangTrajModule | None = None
) -> tuple[Policy, dict[str, Any]]:
    """The policy `request` describes for `scenario`, and a JSON-ready description of it (driven and
    prompted track ids, checkpoint, guidance). `module`, when given, is the already loaded checkpoint
    (it must be `request.checkpoint`, or the shipped one). Raises InputError on bad input."""
    if request.policy not in POLICIES.names():
        raise InputError(f"unknown policy {request.policy!r}; known: {', '.join(POLICIES.names())}", where="--policy")
    sim_agents = sim_agent_indices(scenario)
    if not len(sim_agents):
        raise InputError(f"scenario {scenario.scenario_id} has no agent valid at its current step", where="agents")
    model_only = request.prompts or request.adversary is not None or request.target is not None or request.guidance
    if request.policy != "langtraj":
        if model_only:
            raise InputError(f"prompts and guidance need the langtraj policy, not {request.policy}", where="--policy")
        policy = POLICIES.create(request.policy)
        driven = policy.drives(scenario, sim_agents)
        return policy, {"driven_ids": [int(i) for i in scenario.agents.ids[driven]]}

    from langtraj.training.run import module_from_checkpoint

    checkpoint = request.checkpoint or shipped_checkpoint()
    module = module or module_from_checkpoint(checkpoint)
    prompt = merged_prompt(scenario, request.prompts)
    driven = prioritized_agents(scenario, module.train_config.data.max_agents)  # what LangTrajPolicy drives
    slots = LangTrajPolicy.slots(scenario, driven)
    terms = _collision_term(scenario, slots, request) + _guidance_terms(request.guidance)
    policy = LangTrajPolicy(
        module.model,
        module.train_config.data,
        prompt=prompt,
        terms=terms,
        candidates=request.candidates,
        steps=request.steps,
        guidance_weight=request.cfg,
        guidance_scale=request.guidance_scale,
    )
    described = {
        "checkpoint": str(checkpoint),
        "driven_ids": [int(i) for i in scenario.agents.ids[driven]],
        "prompts": list(request.prompts),
        "prompted_ids": list(prompt.mentions) if prompt else [],
        "adversary": request.adversary,
        "target": request.target,
        "guidance": [f"{t.cost.name}={t.weight:g}" for t in terms],
        "candidates": request.candidates,
        "ddim_steps": request.steps,
        "cfg": request.cfg,
    }
    return policy, described
