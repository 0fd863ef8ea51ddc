"""Candidate planning at each replan of a `LangTrajPolicy` (docs/simulation.md, 'Policies'): the model's input per
rollout, M candidates sampled with the guidance, the hard constraints' projection and polish, warm-started or
rolling plans, prompts' kept plans and adherence, and the selector's choice, executed. The policy's settings and
what it keeps for a simulation (`LangTrajRun`) are `sim.policies`'; this module is how a replan uses them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.frames import Origin, poses_to_world
from langtraj.guidance import GuidanceScene, GuidanceTerm, reconstruction_guidance
from langtraj.guidance.costs import signed_road_distance
from langtraj.guidance.projection import (
    HardConstraints,
    ProjectionAgents,
    current_overlaps,
    project_plans,
    projection_hook,
)
from langtraj.interdrive.dataset import PromptEntry
from langtraj.model.batch import SceneBatch
from langtraj.model.config import SampleConfig
from langtraj.model.dynamics import Unicycle
from langtraj.model.features import MapArrays, collate_scenes, sample_map, scene_sample
from langtraj.model.langtraj import LangTraj
from langtraj.model.scene_encoder import MapContext
from langtraj.scenario.model import STEP_SECONDS
from langtraj.sim.config import SimRequest
from langtraj.sim.external import CLEARANCE_ITERATIONS, accelerations_only, external_acceleration, pin_external
from langtraj.sim.prompt_replan import Guidance, GuidanceOf, PromptReplans, shifted_plan, with_prompt_guidance
from langtraj.sim.scripted import script_state
from langtraj.sim.selection import CandidateSelector, chosen_states
from langtraj.sim.world import SimWorld


def on_road_vehicles(scene: GuidanceScene, xy: Tensor, vehicles: Tensor, external: Sequence[int]) -> Tensor:
    """bool [scene agents]: the driven vehicles (`vehicles` bool [A_d], positions xy [A_d, 2] at the start) whose
    centre is on the road there, which the hard constraints keep on it (one that starts off it, in a car park or
    a driveway, is left where the model puts it); never an external agent; none on a map without road edges."""
    out = torch.zeros(scene.num_agents, dtype=torch.bool)
    if scene.road_edges.shape[0] == 0:
        return out
    on_road = signed_road_distance(xy.to(scene.road_edges), scene) <= 0
    out[: len(vehicles)] = vehicles & on_road
    out[list(external)] = False
    return out & scene.agent_valid.cpu()


def hold(states: Tensor, current: Tensor, slots: Sequence[int]) -> Tensor:
    """`states` [..., A, T, 4] with the agents in `slots` standing at their current pose (`current` [..., A, 4])."""
    if not slots:
        return states
    still = current.clone()
    still[..., list(slots), 3] = 0.0
    return pin_external(states, still, slots)


@dataclass
class LangTrajRun:
    """What one simulation of a `LangTrajPolicy` keeps: the sample sizes for its driven agents, the start's
    scene frame, map and guidance scene (fixed across replans, so costs and the map stay put), the terms,
    the selector, one noise generator per rollout, and what its prompts steer (`sim.prompt_replan`)."""

    data: SampleConfig
    origin: Origin
    map_arrays: MapArrays
    map_context: MapContext  # the map encoded once (one row, shared by every rollout and replan)
    scene: GuidanceScene
    terms: tuple[GuidanceTerm, ...]
    selector: CandidateSelector
    generators: list[torch.Generator]
    prompt: PromptReplans = field(default_factory=PromptReplans)
    external: tuple[int, ...] = ()  # slots of the world's external agents: seen, forecast, never moved
    clearance: tuple[GuidanceTerm, ...] = ()  # the others kept clear of the external agents, in a step of its own
    kept_on_road: Tensor | None = None  # bool [A]: the vehicles the hard constraints keep on the road
    held: tuple[int, ...] = ()  # slots of the agents parked in the log, held where they stand (`hold_parked`)
    executed: dict[int, tuple[int, Tensor]] = field(default_factory=dict)
    """Per rollout: the step and the actions [A, N, 2] (physical) of the plan executed from it, which the next
    replan warm-starts from (`SimRequest.warm_steps`)."""
    rolling: dict[int, tuple[int, Tensor]] = field(default_factory=dict)
    """Per rollout: the step the next replan is due and its candidates' rolling plans [M, A, N, 2] (network units,
    `SimRequest.rolling`)."""


class CandidatePlanning:
    """How a `LangTrajPolicy` plans at each replan (`plan`): what it reads is the policy's (declared here, set by
    `LangTrajPolicy.__init__`: its request's settings and what the constructor takes besides; docs/simulation.md)."""

    model: LangTraj
    data: SampleConfig
    request: SimRequest  # the settings, defaults resolved (`sim.policies.resolved`)
    prompt: PromptEntry | None
    rollout_batch: int
    max_grad_norm: float | None
    free: tuple[int, ...]
    constraints: HardConstraints | None  # the hard constraints, if any

    def plan(self, world: SimWorld, state: LangTrajRun, step: int, horizon: int) -> np.ndarray:
        every = self.roll_steps
        if every is not None and horizon != every and step + horizon < world.end:
            rolled, asked = every * STEP_SECONDS, horizon * STEP_SECONDS
            raise InputError(
                f"this checkpoint's plans roll by {rolled:g} s; replan every {rolled:g} s, not {asked:g} s",
                where="--rolling",
            )
        chunk = self.rollout_batch or world.num_rollouts
        plans = [
            self._plan_rollouts(world, state, step, group)
            for lo in range(0, world.num_rollouts, chunk)
            for group in state.prompt.grouped(list(range(lo, min(lo + chunk, world.num_rollouts))))
        ]
        return np.concatenate(plans, axis=0)[:, :, : max(horizon, 1)]

    def _sample(self, world: SimWorld, state: LangTrajRun, step: int, rollout: int) -> dict[str, Any]:
        """The model's input for one rollout at `step`: its simulated past in the start's frame, and the start's
        map or (`refresh_map`) the map around where its agents are now."""
        scenario = world.scenario_at(rollout, step)
        map_arrays = state.map_arrays
        if self.request.refresh_map and step != world.start:
            map_arrays = sample_map(scenario, world.driven, state.origin, state.data)
        sample = scene_sample(scenario, state.data, agents=world.driven, origin=state.origin, map_arrays=map_arrays)
        if self.prompt is not None and self.request.levers.text:
            ids = sample["agent_id"][: len(world.driven)].tolist()
            waiting = state.prompt.waiting_slots(rollout)  # a staged behaviour not started: as if unprompted
            started = state.prompt.started_sentences(rollout)
            for slot, sentence in self.prompt.sentences(ids).items():
                if slot not in waiting:
                    sentence = state.prompt.steering.sentences.get(int(ids[slot]), sentence)
                    sample["text"][slot] = started.get(int(ids[slot]), sentence)
            sample["interaction_labelled"] = np.bool_(self.prompt.subtype is not None)
        return sample

    def _plan_rollouts(self, world: SimWorld, state: LangTrajRun, step: int, rollouts: list[int]) -> np.ndarray:
        device = next(self.model.parameters()).device
        batch = collate_scenes([self._sample(world, state, step, r) for r in rollouts]).to(device)
        m = self.request.candidates
        generators = [state.generators[r] for r in rollouts]

        def noise(shape: tuple[int, ...]) -> Tensor:  # sample-major rows: [M * R, ...]
            per_rollout = [torch.randn((m, *shape[1:]), generator=g) for g in generators]
            drawn = torch.stack(per_rollout, dim=1).reshape(shape).to(device)
            return drawn if self.request.temperature == 1.0 else drawn * self.request.temperature

        horizon = self.model.horizon_steps  # what the model plans
        state.prompt.stage(world, step, rollouts)
        steered = state.prompt.terms(step, world.start, horizon, rollouts[0] if len(rollouts) == 1 else None)
        accel = external_acceleration(world, state.external, step, rollouts).to(device)
        prompt_terms = tuple(t for group in steered for t in group)
        terms = state.terms + prompt_terms + state.clearance
        hook = None
        scripted = self._scripted(world, state, step, rollouts, batch, accel)
        integrate = self._integrator(state, batch, accel, m, scripted)
        if terms:

            def by(rollout: Callable[[Tensor], Tensor]) -> GuidanceOf:
                def guidance(chosen: tuple[GuidanceTerm, ...], norm: float | None, iterations: int = 1) -> Guidance:
                    return reconstruction_guidance(
                        chosen,
                        state.scene,
                        rollout,
                        scale=self.request.guidance_scale,
                        num_steps=self.model.schedule.num_steps,
                        max_grad_norm=norm,
                        iterations=iterations,
                    )

                return guidance

            guidance = by(integrate)
            hook = guidance(state.terms, self.max_grad_norm) if state.terms else None
            hook = with_prompt_guidance(hook, prompt_terms, guidance)  # its own, larger step after the scene's
            clear = by(lambda x: integrate(accelerations_only(x)))  # the others make room by braking, not swerving
            hook = with_prompt_guidance(hook, state.clearance, clear, iterations=CLEARANCE_ITERATIONS)
        exempt = None if self.constraints is None else self._exempt(state, batch.current_state)  # once a replan
        if exempt is not None:
            hook = self._projection(state, batch, exempt, m, integrate, then=hook)
        start = self._warm_start(state, step, rollouts)
        common = {
            "guidance_weight": self.request.cfg,
            "guidance": hook,
            "noise": noise,
            "map_context": None if self.request.refresh_map and step != world.start else state.map_context,
            "local": None if self.request.dense_attention else self.data.local_attention(),
        }
        if self.request.rolling:
            states, actions = self._roll(state, step, rollouts, batch, **common)
        else:
            states, actions = self.model.sample(
                batch,
                m,
                steps=self.request.steps,
                start=start,
                start_steps=None if start is None else self.request.warm_steps,
                **common,
            )
        if scripted is not None:  # the scripted speeds as executed, not as the model's own integration had them
            actions = with_script(actions, scripted)
            units = self.model.to_units(actions).reshape(-1, *actions.shape[2:])
            states = integrate(units).reshape(*actions.shape[:2], *states.shape[2:])
        states = hold(pin_external(states, batch.current_state, state.external, accel), batch.current_state, state.held)
        states, actions = state.prompt.offer_kept_plans(
            step,
            rollouts,
            states,
            actions,
            self.model.dynamics.steps_per_action,
            self._realiser(state, batch, accel, exempt, scripted=scripted),
        )
        first = state.prompt.adherence(world, state.origin, state.scene, step, rollouts, states, steered)
        choice = state.selector.select(states, state.scene, terms, first)  # states [M, R, A, T, 4], scene frame
        executed, chosen_actions = chosen_states(states, choice), chosen_states(actions, choice)
        config = self.constraints
        if config is not None and config.on_choice and choice.dim() == 2:  # assembled from different candidates
            fixed = state.prompt.judged_slots()  # what a prompted agent chose to do what it is asked is kept
            realise = self._realiser(state, batch, accel, exempt, fixed=fixed, as_given=False, scripted=scripted)
            executed, chosen_actions = (made[0] for made in realise(chosen_actions))
        state.prompt.keep(step, rollouts, chosen_actions)
        if self.request.warm_steps is not None:
            state.executed.update({r: (step, chosen_actions[n].detach()) for n, r in enumerate(rollouts)})
        chosen = executed[:, : len(world.driven)].double().cpu().numpy()
        return poses_to_world(chosen, state.origin)

    def _scripted(
        self, world: SimWorld, state: LangTrajRun, step: int, rollouts: list[int], batch: SceneBatch, accel: Tensor
    ) -> Tensor | None:
        """The actions [R, A, N, 2] (physical; NaN: the model's) that the behaviours executing a manoeuvre exactly set
        in this replan's plans of `rollouts` (`PromptReplans.scripts`, `BehaviourKind.script`: a braking lead, a
        cut-in), planned from the agents' current states (scene frame) and the external agents' accelerations
        `accel` [R, A_e]; None where none does."""
        scripts = [state.prompt.scripts(world.start, rollout) for rollout in rollouts]
        if not any(scripts):
            return None
        dynamics, initial = self.model.dynamics, batch.current_state.detach().double().cpu().numpy()
        sizes = batch.agent_size.detach().double().cpu().numpy()
        if not isinstance(dynamics, Unicycle):  # a script plans acceleration and yaw rate
            raise InputError(f"scripted manoeuvres need the unicycle dynamics, not {dynamics.name!r}", where="dynamics")
        n = self.model.config.num_actions
        out = torch.full((len(rollouts), initial.shape[1], n, 2), float("nan"))
        external = list(state.external)
        for column, planned in enumerate(scripts):
            for steering, since, script in planned:
                other = steering.other_slot
                other_accel = float(accel[column, external.index(other)]) if other in external else 0.0
                memory = state.prompt.memory.setdefault((rollouts[column], steering.slot), {})
                now = script_state(
                    steering, since, step, initial[column], sizes[column], other_accel, dynamics, n,
                    dynamics.steps_per_action, memory,
                )  # fmt: skip
                if len(now.path) >= 2:
                    out[column, steering.slot] = torch.as_tensor(script.plan(now), dtype=out.dtype)
        return None if torch.isnan(out).all() else out.to(next(self.model.parameters()).device)

    def _integrator(
        self, state: LangTrajRun, batch: SceneBatch, accel: Tensor, copies: int, scripted: Tensor | None = None
    ) -> Callable[[Tensor], Tensor]:
        """States [copies * R, A, T, 4] from network-unit actions of `copies` candidates of each of the batch's R
        rollouts (sample-major rows): external agents at their forecast (`accel` [R, A]), not the model's guess, held
        agents where they stand, and the actions a script sets (`scripted` [R, A, N, 2], `_scripted`) in place of the
        model's, so that guidance and selection see the speeds that will be executed."""
        initial = batch.current_state.repeat(copies, 1, 1)
        types, lengths = batch.agent_type.repeat(copies, 1), batch.agent_size[..., 0].repeat(copies, 1)
        external_accel, model = accel.repeat(copies, 1), self.model
        script = None if scripted is None else scripted.repeat(copies, 1, 1, 1)

        def integrate(x: Tensor) -> Tensor:
            if script is not None:
                x = model.to_units(with_script(model.from_units(x), script))
            pinned = pin_external(model.integrate(initial, types, lengths, x), initial, state.external, external_accel)
            return hold(pinned, initial, state.held)

        return integrate

    def _realiser(
        self,
        state: LangTrajRun,
        batch: SceneBatch,
        accel: Tensor,
        exempt: Tensor | None,
        fixed: Sequence[int] = (),
        as_given: bool = True,
        scripted: Tensor | None = None,
    ) -> Callable[[Tensor], tuple[Tensor, Tensor]]:
        """Makes candidates of each rollout from physical actions [R, A, N, 2]: states [K, R, A, T, 4] and actions
        [K, R, A, N, 2] of the plan as sampling makes one (projected onto the road and apart, and refitted, when the
        hard constraints are on, `exempt` being `_exempt`'s pairs; the `fixed` slots neither moved nor kept on the
        road) and, with `as_given`, of the plan as given. Offering both keeps a plan that follows a prompt on offer
        where its projection no longer does (docs/simulation.md, 'Prompts that steer')."""
        integrate = self._integrator(state, batch, accel, 1, scripted)

        def realise(actions: Tensor) -> tuple[Tensor, Tensor]:
            given = self.model.to_units(actions if scripted is None else with_script(actions, scripted))
            plans = [given] if as_given or exempt is None else []
            if exempt is not None:
                assert self.constraints is not None
                agents, initial, invert, drive = self._constraints(state, batch, exempt, 1, fixed)
                config, scene = self.constraints, state.scene
                plans.insert(0, project_plans(config, scene, agents, initial, integrate, invert, given, drive))
            made = torch.stack([self.model.from_units(x) for x in plans])
            return torch.stack([integrate(x) for x in plans]), made if scripted is None else with_script(made, scripted)

        return realise

    def _exempt(self, state: LangTrajRun, current: Tensor) -> Tensor:
        """bool [R, A, A]: the pairs the hard constraints never push apart in each rollout, `current` [R, A, 4] being
        its current state: those that overlap now, and an adversary with its target."""
        assert self.constraints is not None
        exempt = current_overlaps(current, state.scene, self.constraints)
        if len(self.free) == 2:
            exempt[:, self.free[0], self.free[1]] = exempt[:, self.free[1], self.free[0]] = True
        return exempt

    def _constraints(
        self, state: LangTrajRun, batch: SceneBatch, exempt: Tensor, copies: int, fixed: Sequence[int] = ()
    ) -> tuple[ProjectionAgents, Tensor, Callable[[Tensor, Tensor], Tensor], Callable[[Tensor, Tensor], Tensor]]:
        """What the hard constraints need over `copies` candidates of each of the batch's rollouts (sample-major
        rows): the agents they move and how, the initial states, the refit (states [K, T, 3] of the rows a mask picks
        to network-unit actions) and the polish's integrator (network-unit actions [K, N, 2] of the rows a mask picks
        to their states, movable agents only). The `exempt` pairs (`_exempt`) are never pushed apart; external and
        held agents and the `fixed` slots never move (nor are the fixed kept on the road); a pull-over's box may reach
        the road edge itself."""
        config = self.constraints
        assert config is not None and state.kept_on_road is not None
        movable = torch.ones_like(state.kept_on_road)
        movable[list(state.external) + list(state.held) + list(fixed)] = False
        road = state.kept_on_road.clone()
        road[list(fixed)] = False
        margin = None
        if state.prompt.steering.kerb_slots:  # a pull-over is asked to the kerb: its box may touch the edge
            margin = torch.full(movable.shape, config.road_margin, device=movable.device)
            margin[list(state.prompt.steering.kerb_slots)] = 0.0
        polish = steer_only = None
        if prompted := list(state.prompt.steering.prompted_slots):  # a prompt's manoeuvre is not braked away
            polish = torch.ones_like(movable)
            if config.steer_prompted:  # steered back inside instead, but a pull-over not away from its kerb
                steer_only = torch.zeros_like(movable)
                steer_only[prompted] = True
                polish[list(state.prompt.steering.kerb_slots)] = False
            else:
                polish[prompted] = False
        exempt = exempt.repeat(copies, 1, 1)
        agents = ProjectionAgents(road, movable, exempt, margin=margin, polish=polish, steer_only=steer_only)
        initial = batch.current_state.repeat(copies, 1, 1)
        types, lengths = batch.agent_type.repeat(copies, 1), batch.agent_size[..., 0].repeat(copies, 1)
        model = self.model
        every = torch.ones(initial.shape[:2] + (model.horizon_steps,), dtype=torch.bool, device=initial.device)

        def invert(states: Tensor, rows: Tensor) -> Tensor:
            actions, _ = model.dynamics.inverse(initial[rows], states, every[rows])
            return model.to_units(actions).clamp(-4.0, 4.0)

        def drive(actions: Tensor, rows: Tensor) -> Tensor:
            return model.integrate(initial[rows], types[rows], lengths[rows], actions)

        return agents, initial, invert, drive

    def _projection(
        self,
        state: LangTrajRun,
        batch: SceneBatch,
        exempt: Tensor,
        copies: int,
        integrate: Callable[[Tensor], Tensor],
        then: Guidance,
    ) -> Guidance:
        """The hard constraints' hook (`guidance.projection`) after `then` over `copies` candidates of each rollout
        (`_constraints`), integrated by `integrate`."""
        assert self.constraints is not None
        agents, initial, invert, drive = self._constraints(state, batch, exempt, copies)
        return projection_hook(
            self.constraints,
            state.scene,
            agents,
            initial,
            integrate,
            invert,
            num_steps=self.model.schedule.num_steps,
            sampler_steps=self.request.steps,
            then=then,
            drive=drive,
        )

    def _roll(
        self, state: LangTrajRun, step: int, rollouts: list[int], batch: SceneBatch, **common: Any
    ) -> tuple[Tensor, Tensor]:
        """`LangTraj.roll` on each rollout's candidates' rolling plans, or from noise at the first replan (no plan
        yet); keeps the plans for the next replan. States [M, R, A, T, 4], actions [M, R, A, N, 2]."""
        every = self.roll_steps
        assert every is not None
        plan = None
        if any(r in state.rolling for r in rollouts):  # `plan` refuses other intervals, so every plan is due now
            due = [state.rolling[r] for r in rollouts]
            assert all(when == step for when, _ in due), f"rolling plans due at {[w for w, _ in due]}, not {step}"
            plan = torch.stack([p for _, p in due], dim=1).flatten(0, 1)  # sample-major rows
        states, actions, nxt = self.model.roll(batch, self.request.candidates, plan, steps=self.request.steps, **common)
        per_rollout = nxt.reshape(self.request.candidates, len(rollouts), *nxt.shape[1:])
        state.rolling.update({r: (step + every, per_rollout[:, n]) for n, r in enumerate(rollouts)})
        return states, actions

    @property
    def roll_steps(self) -> int | None:
        """Scenario steps a rolling plan moves on by at each replan (its replan interval); None without `rolling`."""
        rolls = self.model.rolling
        if not self.request.rolling or rolls is None:
            return None
        return rolls.group * self.model.dynamics.steps_per_action

    def _warm_start(self, state: LangTrajRun, step: int, rollouts: list[int]) -> Tensor | None:
        """Each rollout's executed actions [R, A, N, 2] shifted to `step` (zero actions after their end), or None:
        no warm start asked, a rollout without a plan yet, or a replan between two actions."""
        if self.request.warm_steps is None or any(r not in state.executed for r in rollouts):
            return None
        per_action = self.model.dynamics.steps_per_action
        shifted = []
        for r in rollouts:
            before, actions = state.executed[r]
            left = shifted_plan(actions, step - before, per_action)
            if left is None:
                return None
            shifted.append(left)
        return torch.stack(shifted)


def with_script(actions: Tensor, scripted: Tensor) -> Tensor:
    """Physical actions [..., R, A, N, 2] with those `scripted` [R, A, N, 2] sets (NaN: kept)."""
    script = scripted.to(actions)
    return torch.where(torch.isnan(script), actions, torch.nan_to_num(script))
