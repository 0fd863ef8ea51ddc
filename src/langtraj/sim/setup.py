"""From what a user asks for (`SimRequest`: policy, checkpoint, prompts, adversary and target,
guidance) to a checked policy, built by its registry: bad input is found here, or (a prompt naming an
agent the model does not drive) when the policy is reset at the start of the simulation; either way
before any file is written (docs/simulation.md)."""

from __future__ import annotations

from typing import Any

from langtraj.errors import InputError
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.scenario.model import HISTORY_STEPS, Scenario
from langtraj.sim.config import SimRequest
from langtraj.sim.policies import POLICIES, LoadedModel, Policy
from langtraj.sim.prompt_checks import check_prompts


def build_policy(
    scenario: Scenario, request: SimRequest, loaded: LoadedModel | None = None
) -> tuple[Policy, dict[str, Any]]:
    """The policy `request` describes for `scenario`, and a JSON-ready description of it (driven track
    ids, the policy's settings, the request's prompts, adversary and target). `loaded`, when given, is the
    already loaded checkpoint (it must be `request.checkpoint`, or the shipped one). Raises InputError on
    bad input."""
    cls = POLICIES.get(request.policy, where="--policy")
    if cls.uses_model and scenario.current_index < HISTORY_STEPS - 1:
        raise InputError(
            f"scenario {scenario.scenario_id} has {scenario.current_index} step(s) before its current step; the model "
            f"reads {HISTORY_STEPS - 1} (a {HISTORY_STEPS}-step history): choose a later current step or window",
            where="scenario",
        )
    sim_agents = sim_agent_indices(scenario)
    if not len(sim_agents):
        raise InputError(f"scenario {scenario.scenario_id} has no agent valid at its current step", where="agents")
    if cls.uses_model:  # the one check of typed prompts (the studio's and the env's too); targets come with the policy
        error = check_prompts(scenario, request.prompts, targets=False).first_error()  # the pair: collision_terms
        if error is not None:
            raise InputError(error, where="prompt")
    try:
        policy = cls.from_request(scenario, request, loaded)
    except InputError as exc:
        raise exc.located(where=None if exc.where else "--policy") from None
    driven = policy.drives(scenario, sim_agents)
    described: dict[str, Any] = {"driven_ids": [int(i) for i in scenario.agents.ids[driven]]}
    if cls.uses_model:
        described |= {"prompts": list(request.prompts), "adversary": request.adversary, "target": request.target}
    return policy, described | policy.describe()
