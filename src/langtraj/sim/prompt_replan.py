"""Typed prompts at each replan of a LangTraj simulation (docs/simulation.md, 'Prompts that steer'): the guidance
terms toward each read behaviour's target for what is left of them (`PromptReplans.terms`), their own
reconstruction-guidance step after the scene's (`with_prompt_guidance`), the plan executed at the previous replan
offered again as candidates (`PromptReplans.offer_kept_plans`: projected like a sampled one, and as executed), and
the prompted agents' adherence that selection compares before anything else (`PromptReplans.adherence`, the
selectors' `first`).

What the prompts steer is derived once per simulation from their one reading (`sim.prompts.prompt_steering`); a
`PromptReplans` holds it, with the candidate judge, and keeps what one replan leaves the next (the executed plans).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import torch
from torch import Tensor

from langtraj.frames import Origin, poses_to_world
from langtraj.guidance import GuidanceScene, GuidanceTerm
from langtraj.guidance.steering import Steering
from langtraj.interdrive.behaviour import BEHAVIOURS
from langtraj.interdrive.behaviours import Script, kind
from langtraj.model.diffusion import Guidance
from langtraj.sim.adherence import CandidateJudge
from langtraj.sim.prompts import PromptSteering, conditioning_sentence
from langtraj.sim.staging import Stagings
from langtraj.sim.world import SimWorld

PROMPT_MAX_GRAD_NORM = 2.0
"""Largest gradient norm per agent of the guidance toward a prompt's target (the scene's realism guidance keeps
its own, `max_grad_norm`): chosen on validation windows (docs/experiments.md, 'Prompts that steer')."""
PROMPT_ITERATIONS = 2
"""Gradient steps of the guidance toward a prompt's target at each guided denoising step."""
NEAR_WEIGHT = 1e-4
"""Weight of a prompted agent's distance from its target among candidates that follow its prompt (see
`PromptReplans.adherence`): times `selection.FIRST_WEIGHT`, 1 per unit of c / (1 + c)."""

GuidanceOf = Callable[[tuple[GuidanceTerm, ...], float | None, int], Guidance]
"""Makes the sampler's guidance hook of some terms, with a largest gradient norm and a number of iterations."""


def with_prompt_guidance(
    hook: Guidance | None, terms: tuple[GuidanceTerm, ...], guidance: GuidanceOf, iterations: int = PROMPT_ITERATIONS
) -> Guidance | None:
    """The sampler hook applying `hook` (the scene's guidance, if any), then `terms` (if any: the prompts' targets,
    or the clearance from external agents, `sim.external`) in a step of their own, larger than the scene's
    (`PROMPT_MAX_GRAD_NORM`, `iterations` gradient steps), made by `guidance`."""
    if not terms:
        return hook
    return then(hook, guidance(terms, PROMPT_MAX_GRAD_NORM, iterations))


def then(first: Guidance | None, second: Guidance) -> Guidance:
    """The sampler hook applying `first` (if any), then `second`, to the clean prediction."""
    if first is None:
        return second
    return lambda x0, k, x_k: second(first(x0, k, x_k), k, x_k)


@dataclass
class PromptReplans:
    """What typed prompts steer in one simulation (`steering`, read at its start) and how its candidates are judged
    (`judge`, None without the selection lever or a read behaviour), with what each replan leaves the next: per
    rollout, the step and the actions [A, N, 2] (physical) of the plan executed from it (`kept`), which the next
    replan offers again as a candidate for the prompted agents. Without prompts it steers nothing."""

    steering: PromptSteering = field(default_factory=PromptSteering)
    judge: CandidateJudge | None = None
    kept: dict[int, tuple[int, Tensor]] = field(default_factory=dict)
    stagings: Stagings | None = None
    memory: dict[tuple[int, int], dict[str, Any]] = field(default_factory=dict)
    """Per (rollout, agent slot): what its script decided at the steps executed so far (`ScriptState.memory`)."""
    """The behaviours that start at their trigger and where each started per rollout (`sim.staging`); None: none."""

    def stage(self, world: SimWorld, step: int, rollouts: list[int]) -> None:
        """Start the staged behaviours whose trigger holds at `step` in `rollouts` (`Stagings.update`)."""
        if self.stagings:
            self.stagings.update(world.scenario_at, step, rollouts)

    def steerings(self, start: int, rollout: int | None = None) -> list[tuple[Steering, int]]:
        """Each steering toward a target with the step it is timed from: those anchored at the simulation's `start`
        and, in `rollout`, the staged ones started there (`Stagings.started_in`) and those keeping a staged agent's
        place until it starts (timed from the start)."""
        out = [(s, start) for s in self.steering.steerings]
        if self.stagings and rollout is not None:
            out += [(anchor.steering, anchor.step) for _, anchor in self.stagings.started_in(rollout)]
            out += [(keep, start) for keep in self.stagings.keeping_in(rollout)]
        return out

    def terms(self, step: int, start: int, horizon: int, rollout: int | None = None) -> list[list[GuidanceTerm]]:
        """The guidance terms toward each target (one list per `steerings(start, rollout)`) for a replan at `step` of
        a simulation started at `start`, over the `horizon` steps the model plans: timed from the start, or from where
        a staged behaviour started."""
        return [s.terms(step - since, horizon) for s, since in self.steerings(start, rollout)]

    def scripts(self, start: int, rollout: int) -> list[tuple[Steering, int, Script]]:
        """(steering, step it is timed from, script) of each behaviour in `rollout` that executes a manoeuvre exactly
        (`BehaviourKind.script`), anchored at the simulation's `start` or where a staged one started."""
        out = []
        for steering, since in self.steerings(start, rollout):
            if steering.declared is None and (script := kind(steering.target.behaviour).script(steering.target)):
                out.append((steering, since, script))
        return out

    def grouped(self, rollouts: list[int]) -> list[list[int]]:
        """`rollouts` in groups that share their prompts' guidance: all together, or one by one where behaviours are
        staged (each rollout's targets are its own)."""
        return [[r] for r in rollouts] if self.stagings else [rollouts]

    def started_sentences(self, rollout: int) -> dict[int, str]:
        """Track id -> the sentence a staged behaviour started in `rollout` conditions the model on in place of the
        typed one: for a kind the model never saw, the one it is conditioned as (`conditioning_sentence`); for words
        with timing, the kind's own sentence, never the timing words, which are the staging's job."""
        if not self.stagings:
            return {}
        out = {}
        for staged, anchor in self.stagings.started_in(rollout):
            target = anchor.target
            sentence = conditioning_sentence(target)
            if sentence is None and staged.reading.condition:  # typed with timing words: the kind's own sentence
                sentence = BEHAVIOURS[target.behaviour].text(target.track_id, target.other_id)
            if sentence is not None:
                out[target.track_id] = sentence
        return out

    def waiting_slots(self, rollout: int) -> set[int]:
        """The slots whose staged behaviour has not started in `rollout`: conditioned as if unprompted."""
        return self.stagings.waiting_slots(rollout) if self.stagings else set()

    def judged_slots(self) -> list[int]:
        """The slots whose kept plan `offer_kept_plans` offers: each prompted agent, and a pair behaviour's other
        agent (it keeps its side of the plan too)."""
        asks = self.judge.asks if self.judge else ()
        return sorted({slot for ask in asks for slot in (ask.slot, ask.other_slot) if slot is not None})

    def offer_kept_plans(
        self,
        step: int,
        rollouts: list[int],
        states: Tensor,
        actions: Tensor,
        per_action: int,
        realise: Callable[[Tensor], tuple[Tensor, Tensor]],
    ) -> tuple[Tensor, Tensor]:
        """The candidates' states [M, R, A, T, 4] and actions [M, R, A, N, 2] (physical) with those made of the kept
        plans when a judge is there and every rollout has one: for each judged slot what is left of the actions it
        executed from the previous replan (`shifted_plan`), for the other agents candidate 0's, made into candidates by
        `realise` (actions [R, A, N, 2] to states [K, R, A, T, 4] and actions [K, R, A, N, 2]: integrated as sampling
        integrates, external agents pinned; projected onto the road and apart when the hard constraints are on, and
        then offered as executed too). A plan that did what the prompt asks stays on offer, so a replan that samples
        no such candidate keeps to it instead of putting the behaviour off (plan reuse in receding-horizon control),
        kept to the road and apart from the others where its projection still does what is asked. Otherwise the
        candidates unchanged."""
        if self.judge is None or any(r not in self.kept for r in rollouts):
            return states, actions
        extra = actions[0].clone()  # [R, A, N, 2]
        slots = self.judged_slots()
        for n, r in enumerate(rollouts):
            before, plan = self.kept[r]
            left = shifted_plan(plan, step - before, per_action)
            if left is None:
                return states, actions
            extra[n, slots] = left[slots].to(extra)
        kept_states, kept_actions = realise(extra)
        return torch.cat([states, kept_states.to(states)]), torch.cat([actions, kept_actions.to(actions)])

    def adherence(
        self,
        world: SimWorld,
        origin: Origin,
        scene: GuidanceScene,
        step: int,
        rollouts: list[int],
        states: Tensor,
        steered: list[list[GuidanceTerm]],
    ) -> Tensor | None:
        """`first` for selection [M, R, A] of candidates `states` [M, R, A, T, 4] (scene frame of `origin`) of
        `rollouts` at `step`, with this replan's terms toward the targets (`steered`, from `terms`): 1 where a
        prompted agent's candidate does not follow its prompt (`sim.adherence`), plus up to 0.5 by how far it is from
        its target (n, its guidance cost c as c / (1 + c)), so that among candidates that all miss the nearest comes
        first; and `NEAR_WEIGHT` x n for every candidate, so that among those that follow, one that does it now beats
        one that puts it off to a later replan (as much as a tenth of a disk overlap weighs in `per_agent`). A pair
        behaviour's miss also counts for the other agent's candidate (judged with the prompted agent's candidate of
        the same index): yielding to @7 or going before it is something the two do together. None without a judge."""
        if self.judge is None:
            return None
        m, r = states.shape[:2]
        plans = poses_to_world(states[:, :, : len(world.driven)].detach().double().cpu().numpy(), origin)
        found = self.judge.misses(rollouts, step, plans)  # [K, M, R]
        if self.stagings:  # a staged behaviour not started yet is not missed
            for k, staged in enumerate(self.stagings.staged):
                for column, rollout in enumerate(rollouts):
                    if staged.ask is not None and self.stagings.is_waiting(rollout, k):
                        found[staged.ask, :, column] = False
        misses = torch.as_tensor(found, dtype=states.dtype)
        first = states.new_zeros(states.shape[:3])
        steerings = self.steerings(world.start, rollouts[0] if len(rollouts) == 1 else None)
        by_slot = {s.slot: terms for (s, _), terms in zip(steerings, steered, strict=True)}
        flat = states.reshape(m * r, *states.shape[2:])
        with torch.no_grad():
            for ask, miss in zip(self.judge.asks, misses, strict=True):
                near = states.new_zeros(m, r)
                for term in by_slot.get(ask.slot, []):
                    near = near + term.weight * term.cost(flat, scene).reshape(m, r)
                nearness = near / (1.0 + near)
                miss = miss.to(states.device)
                first[:, :, ask.slot] += miss * (1.0 + 0.5 * nearness) + NEAR_WEIGHT * nearness
                if ask.other_slot is not None:  # a pair behaviour is the pair's: the other makes way, or leads
                    first[:, :, ask.other_slot] += miss
        return first

    def keep(self, step: int, rollouts: list[int], executed: Tensor) -> None:
        """Keep the actions [R, A, N, 2] (physical) executed from `step` by `rollouts`, for the next replan to offer
        (only with a judge: nothing else reads them)."""
        if self.judge is not None:
            self.kept.update({r: (step, executed[n].detach()) for n, r in enumerate(rollouts)})


def shifted_plan(actions: Tensor, elapsed: int, per_action: int) -> Tensor | None:
    """What is left of a plan's actions [..., N, 2] (physical) `elapsed` scenario steps after it was made: shifted
    by the actions executed since, the freed end at zero (acceleration and yaw rate: constant speed and heading).
    None when `elapsed` falls between two actions or past the plan's end."""
    done, rest = divmod(elapsed, per_action)
    if rest or done >= actions.shape[-2]:
        return None
    return torch.cat([actions[..., done:, :], torch.zeros_like(actions[..., :done, :])], dim=-2)
