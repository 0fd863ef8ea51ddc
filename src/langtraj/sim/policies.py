"""Policies: what decides the driven agents' next states at each replan of a closed-loop simulation
(docs/simulation.md, 'Policies').

One interface, registered by name and built from a simulation request (`Policy.from_request`): LangTraj
(a checkpoint, optionally with text, classifier-free and cost guidance), constant velocity, log replay,
and the CTG++-style baseline (LangTraj without text, steered by a fixed library of guidance costs per
prompt label, the role LLM-written costs play in the paper's comparison). A policy `drives` some sim
agents (the model policies: every sim agent unless capped); the world moves the others as the policy's
`undriven` says, by constant velocity from their history unless log-following is asked for explicitly.
What a policy keeps for one simulation (random streams, the scene frame, the map, the sample sizes) is
the state `reset` returns, so one policy object can run several simulations.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch

from langtraj.errors import InputError
from langtraj.frames import Origin, poses_to_frame
from langtraj.guidance import (
    GuidanceScene,
    GuidanceTerm,
    HeadwayCost,
    NoCollisionCost,
    OnRoadCost,
)
from langtraj.guidance.base import FinalSteps
from langtraj.guidance.library import terms_for_prompt
from langtraj.guidance.projection import (
    HardConstraints,
)
from langtraj.interdrive.behaviour import BEHAVIOURS
from langtraj.interdrive.dataset import PromptEntry
from langtraj.model.checkpoint import load_model
from langtraj.model.config import SampleConfig
from langtraj.model.dynamics import Unicycle
from langtraj.model.features import collate_scenes, map_coverage, sample_map, scene_frame, scene_sample
from langtraj.model.langtraj import LangTraj
from langtraj.registry import Registry
from langtraj.roads import MapIndex
from langtraj.rollouts.baselines import BASELINES
from langtraj.scenario.model import Scenario
from langtraj.scenario.selection import prioritized_agents
from langtraj.scenario.types import AgentType
from langtraj.sim import scripted
from langtraj.sim.adherence import CandidateJudge
from langtraj.sim.candidates import CandidatePlanning, LangTrajRun, on_road_vehicles
from langtraj.sim.checkpoints import shipped_checkpoint
from langtraj.sim.config import ALL_LEVERS, PromptLevers, SimRequest, flag_of
from langtraj.sim.parked import parked_in_history
from langtraj.sim.prompt_replan import PromptReplans
from langtraj.sim.prompts import PromptSteering, check_prompt_driven, merged_prompt, prompt_steering, read_prompts
from langtraj.sim.selection import SELECTORS
from langtraj.sim.staging import Stagings, keeping
from langtraj.sim.terms import collision_terms, scene_wide_terms
from langtraj.sim.world import SimWorld

DEFAULT_ON_ROAD = 1.0
"""Weight of the on-road guidance a LangTraj simulation applies to every driven agent unless told
otherwise (`--on-road`; 0 turns it off): chosen by measurement (docs/experiments.md, 'Closed-loop
realism, every agent driven'), not in the paper."""
DEFAULT_NO_COLLISION = 1.0
"""Weight per agent pair of the no-collision guidance a LangTraj simulation applies between its driven
agents unless told otherwise (`--no-collision`; 0 turns it off), chosen like `DEFAULT_ON_ROAD`."""
DEFAULT_GUIDED_STEPS: int | None = 3
"""The last denoising steps of each sample at which the on-road and no-collision guidance apply unless
told otherwise (`--guided-steps`; None: every step): chosen on validation windows like `DEFAULT_ON_ROAD`,
at less cost than guiding all five (docs/experiments.md, 'Guidance on fewer steps')."""
DEFAULT_SELECTOR = "per_agent"
"""Candidate selection without steering guidance (prompts' costs, collision or `--guidance` terms, which
use `min_guidance`): chosen by measurement like `DEFAULT_ON_ROAD`; the paper's is `min_collision`."""

DEFAULT_EXTERNAL_CLEARANCE = 10.0
"""Weight of the guidance that keeps the driven agents behind the world's external agents they follow (an ego
under test; `sim.external`), chosen on a constructed follower scene (docs/testing.md, 'How the other agents
react'); no term without external agents, so `simulate` is unchanged."""
EXTERNAL_BUFFER_M = 2.0
"""The gap guidance keeps behind an external agent's forecast, bumper to bumper (m)."""

DEFAULT_HARD_CONSTRAINTS: HardConstraints | None = HardConstraints(steps=1)
"""The hard constraints (`guidance.projection`) a LangTraj simulation applies unless told otherwise
(`--hard-constraints N`; 0 turns them off): at the last denoising step, chosen on validation maps (as good as the
last 2 or 3 there, at less cost and kinematic change; docs/experiments.md, 'Traffic that stays on the road'), not
in the paper."""

DEFAULT_HOLD_PARKED = False
"""Whether a LangTraj simulation holds the agents parked in the log where they stand unless a prompt names them
(`--hold-parked` / `--no-hold-parked`), chosen like `DEFAULT_HARD_CONSTRAINTS`."""

GUIDANCE_ONLY = PromptLevers(text=False, guidance=True, selection=False)
"""The levers of the CTG++-style baseline (`GuidanceBaselinePolicy`)."""

LoadedModel = tuple[LangTraj, SampleConfig]
"""A trained model and the sample configuration it was trained with (`langtraj.model.load_model`)."""


class Policy(ABC):
    """Plans the driven agents' states (world x, y, heading, speed at 10 Hz) from each rollout's past."""

    name: ClassVar[str]

    @classmethod
    def from_request(cls, scenario: Scenario, request: SimRequest, loaded: LoadedModel | None = None) -> Policy:
        """The policy `request` asks for on `scenario` (`loaded`: a model already in memory, for policies
        that use one). Raises InputError for what this policy cannot do. Model-free policies take no
        prompts and no guidance."""
        if asked := request.model_options():
            model_policies = ", ".join(c.name for c in POLICIES.classes() if c.uses_model)
            listed, verb = (f"{', '.join(asked[:-1])} and {asked[-1]}", "need") if asked[1:] else (asked[0], "needs")
            raise InputError(f"{listed} {verb} a model policy ({model_policies}), not {cls.name}")
        return cls()

    uses_model: ClassVar[bool] = False
    undriven: str = "constant_velocity"  # how the sim agents it does not drive move (`sim.config.UNDRIVEN`)

    def drives(self, scenario: Scenario, sim_agents: np.ndarray) -> np.ndarray:
        """Scenario rows this policy drives, a subset of `sim_agents` (default: all of them)."""
        return sim_agents

    def describe(self) -> dict[str, Any]:
        """JSON-ready settings of this policy for a simulation summary (none by default)."""
        return {}

    def reset(self, world: SimWorld, seed: int) -> Any:
        """The state of a new simulation of `world` (random streams, scene frame, map, ...), passed back to
        every `plan` of that simulation. None by default."""
        return None

    @abstractmethod
    def plan(self, world: SimWorld, state: Any, step: int, horizon: int) -> np.ndarray:
        """States [R, A_driven, >= horizon, 4] for steps step+1 ... of every rollout."""

    def act(self, world: SimWorld, state: Any, step: int, poses: np.ndarray) -> np.ndarray:
        """The driven agents' states at step+1 [R, A_driven, 4] given what the last `plan` planned for it (`poses`),
        called at every step between and at replans: a policy that drives some agents at the simulation's rate
        corrects them from the scene at `step` (`sim.scripted`); by default the plan."""
        return poses

    def report(self, world: SimWorld, state: Any) -> dict[str, Any]:
        """JSON-ready figures of a finished simulation for its summary (none by default)."""
        return {}


POLICIES: Registry[Policy] = Registry("policy")


@POLICIES.register
class ConstantVelocityPolicy(Policy):
    """Every driven agent keeps its velocity by the WOSAC constant-velocity rule (`rollouts.baselines`:
    the displacement of its last step, or its reported velocity where the step before is unknown),
    replanned from the simulated state; so its rollouts are that baseline's."""

    name = "constant_velocity"

    def plan(self, world: SimWorld, state: Any, step: int, horizon: int) -> np.ndarray:
        rule = BASELINES.get("constant_velocity")()
        plans = []
        for r in range(world.num_rollouts):
            tracks = world.states[r, world.driven].astype(np.float64)
            plans.append(rule.model_states(tracks, world.valid[r, world.driven], step, horizon))  # [A, H, 4]
        return np.stack(plans)


@POLICIES.register
class LogReplayPolicy(Policy):
    """No agent is driven: everyone follows the log (constant velocity past its end). A labelled baseline
    that reads the future: its rollouts are flagged and cannot be submitted."""

    name = "log_replay"
    undriven = "log"

    def drives(self, scenario: Scenario, sim_agents: np.ndarray) -> np.ndarray:
        return sim_agents[:0]

    def plan(self, world: SimWorld, state: Any, step: int, horizon: int) -> np.ndarray:
        return np.zeros((world.num_rollouts, 0, horizon, 4))


def model_agents(scenario: Scenario, max_driven: int | None = None) -> np.ndarray:
    """The scenario rows a model policy drives, in slot order: every sim agent, most important first
    (`prioritized_agents`: objects of interest, the SDC and tracks to predict first), or the `max_driven`
    most important when capped."""
    return prioritized_agents(scenario, max_driven)


def hard_constraints(steps: int | None, sampler_steps: int) -> HardConstraints | None:
    """The hard constraints a request's `--hard-constraints N` asks for: None gives `DEFAULT_HARD_CONSTRAINTS`, 0
    none, N the projection at the last N of the `sampler_steps` denoising steps."""
    if steps is None:
        return DEFAULT_HARD_CONSTRAINTS
    if steps == 0:
        return None
    if steps > sampler_steps:
        raise InputError(f"must be in [0, {sampler_steps}] (the DDIM steps), got {steps}", where="--hard-constraints")
    return HardConstraints(steps=steps)


def resolved(request: SimRequest) -> SimRequest:
    """`request` with a LangTraj simulation's defaults for the settings it leaves to the policy (None): the one
    place they are chosen (`DEFAULT_ON_ROAD`, `DEFAULT_NO_COLLISION`, `DEFAULT_GUIDED_STEPS` capped at the
    `steps`, `DEFAULT_EXTERNAL_CLEARANCE`, `DEFAULT_HOLD_PARKED`). The hard constraints' default is
    `hard_constraints`'; the selector's depends on the guidance (`LangTrajPolicy.default_selector`)."""
    guided = request.guided_steps
    if guided is None:
        guided = min(DEFAULT_GUIDED_STEPS or request.steps, request.steps)
    return replace(
        request,
        on_road=DEFAULT_ON_ROAD if request.on_road is None else request.on_road,
        no_collision=DEFAULT_NO_COLLISION if request.no_collision is None else request.no_collision,
        guided_steps=guided,
        external_clearance=(
            DEFAULT_EXTERNAL_CLEARANCE if request.external_clearance is None else request.external_clearance
        ),
        hold_parked=DEFAULT_HOLD_PARKED if request.hold_parked is None else request.hold_parked,
    )


def _check_request(model: LangTraj, request: SimRequest) -> None:
    """Raises InputError, naming the option, for a setting of the `resolved` request that `model` cannot sample with."""

    def check(ok: bool, name: str, message: str) -> None:
        if not ok:
            raise InputError(message, where=flag_of(SimRequest, name))

    steps = request.steps
    for name in ("on_road", "no_collision"):
        weight = getattr(request, name)
        check(math.isfinite(weight) and weight >= 0, name, f"must be finite and >= 0, got {weight}")
    for name in ("guided_steps", "warm_steps"):
        n = getattr(request, name)
        check(n is None or 1 <= n <= steps, name, f"must be in [1, {steps}] (the DDIM steps), got {n}")
    rolling = "this checkpoint was not trained to roll its plans (model.rolling_group is 0)"
    check(not request.rolling or model.rolling is not None, "rolling", rolling)
    both = "a rolling plan is its own warm start; give --rolling or --warm-steps"
    check(not request.rolling or request.warm_steps is None, "rolling", both)
    temperature = request.temperature
    check(math.isfinite(temperature) and 0 < temperature <= 2, "temperature", f"must be in (0, 2], got {temperature}")
    clearance = request.external_clearance
    check(
        math.isfinite(clearance) and clearance >= 0, "external_clearance", f"must be finite and >= 0, got {clearance}"
    )


def external_ids(world: SimWorld) -> set[int]:
    """Track ids of the world's external agents (an ego under a planner)."""
    return {int(world.scenario.agents.ids[row]) for row in world.external}


def slots_of(scenario: Scenario, driven: np.ndarray) -> dict[int, int]:
    """Track id -> model slot of every driven agent (what guidance terms and prompts refer to)."""
    return {int(scenario.agents.ids[row]): slot for slot, row in enumerate(driven)}


@POLICIES.register
class LangTrajPolicy(CandidatePlanning, Policy):
    """Samples `candidates` joint futures per rollout from a LangTraj model at each replan and executes
    the one `selector` picks.

    Its settings are its `request` (`SimRequest`: what `langtraj simulate` states, with the defaults of `resolved`
    for what it leaves at None; the names below are its fields). The constructor takes besides what no option
    states: the model and its `data`, the `prompt` entry (`from_request` merges the request's prompts into one; an
    experiment may pass an InterDrive entry with its labels), guidance `terms` in model slots (`from_request`'s
    collision term for an adversary; the request's scene-wide `guidance` is added to them), the `free` slots the
    no-collision guidance leaves out (an adversary and its target), the `checkpoint` it reports, `constraints`
    (a `HardConstraints` to apply instead of the request's `hard_constraints`, for a polish or choice projection
    of its own), `rollout_batch` and `max_grad_norm`.

    The model drives every sim agent (or the `max_driven` most important, `model_agents` at the start;
    the others move as `undriven` says), however many agents it was trained with: samples are sized for
    the driven agents and the map covers each of them (`SampleConfig.for_agents`). Every replan uses the
    scene frame and map of the start. `prompt` conditions the agents it mentions (with the `levers` on); `terms`
    (agent slots = positions among the driven agents) add reconstruction guidance, scaled by
    `guidance_scale`; `cfg` is classifier-free guidance (-1: ignore text). Each rollout draws
    its noise from its own generator seeded by (seed, rollout), so rollouts batched `rollout_batch` at a
    time give what they give one by one. Without `dense_attention`, in a scene larger than the model's
    training scenes each agent attends to as many nearest agents and map pieces as those scenes held
    (`SampleConfig.local_attention`); with it, to all of them. The realism guidance (`on_road`,
    `no_collision`) applies at the last `guided_steps` of the `steps` denoising steps (by default
    `DEFAULT_GUIDED_STEPS`), on a road field built once per simulation (`GuidanceScene.with_road_field`).
    With `warm_steps` n, a replan starts from what is left of the plan each agent executed (its actions shifted
    by the steps since, the freed end held at zero acceleration and yaw rate), noised to the n-th last of the
    `steps` denoising steps and denoised from there: plans that agree across replans, in n network calls
    (docs/simulation.md, 'Warm-started replans'). None: every replan starts from fresh noise. `temperature`
    scales the sampler's noise (below 1: samples nearer the model's most likely future, less diverse). With
    `refresh_map`, each replan chooses its map pieces around where each rollout's agents are then, as training
    chose them around the agents at the window's current step; otherwise the start's map serves every replan
    (encoded once; agents that drive out of it see no road; docs/simulation.md, 'The map at each replan').
    With `rolling` (a checkpoint trained with `model.rolling_group`), each candidate keeps one rolling plan whose
    noise rises along the future; after a cold start each replan denoises it once and executes its clean first
    actions (`LangTraj.roll`; docs/simulation.md, 'Rolling plans').
    """

    name = "langtraj"
    uses_model = True
    steers_by_prompt: ClassVar[bool] = False  # whether `prompt_terms` derives guidance from the prompt

    def __init__(
        self,
        model: LangTraj,
        data: SampleConfig,
        request: SimRequest | None = None,
        *,
        prompt: PromptEntry | None = None,
        terms: Sequence[GuidanceTerm] = (),
        free: Sequence[int] = (),
        checkpoint: Path | None = None,
        constraints: HardConstraints | None = None,
        rollout_batch: int = 0,
        max_grad_norm: float | None = 0.5,
        typed: bool | None = None,
    ):
        """`typed`: whether the prompts' texts are typed, so read strictly (`sim.prompts.read_prompts`); by default
        they are unless `prompt` is a dataset's labelled entry."""
        request = resolved(request or SimRequest())
        terms = (*terms, *scene_wide_terms(request.guidance))
        if constraints is None:
            constraints = hard_constraints(request.hard_constraints, request.steps)
        if request.candidates < 1 or request.steps < 1 or rollout_batch < 0:
            raise InputError(
                "candidates and steps must be >= 1 and rollout_batch >= 0 "
                f"(got {request.candidates}, {request.steps}, {rollout_batch})"
            )
        if prompt is not None and request.levers.text and model.text_encoder is None:
            raise InputError(
                "this checkpoint has no text branch (a stage-1 model); it cannot condition on a prompt's text "
                "(switch the text lever off to steer by guidance and selection alone)",
                where="prompt",
            )
        if request.selector is not None:
            SELECTORS.get(request.selector, where="selector")
        _check_request(model, request)
        self.model = model.eval()
        self.request = request
        self.data = data.for_inference(text=prompt is not None and request.levers.text)
        self.prompt = prompt
        self.prompt_texts = request.prompts or ((prompt.text,) if prompt else ())
        # Each prompt read once, clause by clause (`sim.prompts`); a dataset prompt's sentence is never refused.
        strict = typed if typed is not None else prompt is None or not _labelled(prompt)
        self.readings = read_prompts(self.prompt_texts, strict=strict)
        self.terms = terms
        self.free = tuple(int(slot) for slot in free)
        self.checkpoint = checkpoint
        self.constraints = constraints
        self.rollout_batch = rollout_batch
        self.max_grad_norm = max_grad_norm

    @classmethod
    def from_request(cls, scenario: Scenario, request: SimRequest, loaded: LoadedModel | None = None) -> LangTrajPolicy:
        checkpoint = request.checkpoint or shipped_checkpoint()
        model, data = loaded or load_model(checkpoint)
        if request.compile and not model.compiled:
            model.compile_steps(training=False)
        slots = slots_of(scenario, model_agents(scenario, request.max_driven))
        terms = collision_terms(scenario, slots, request)
        free = [slots[t] for t in (request.adversary, request.target) if t is not None]  # the collision's pair
        prompt = merged_prompt(scenario, request.prompts)
        return cls(model, data, request, prompt=prompt, terms=terms, checkpoint=checkpoint, free=free)

    @property
    def undriven(self) -> str:  # type: ignore[override]
        return self.request.undriven

    # ------------------------------------------------------------------ which agents
    def drives(self, scenario: Scenario, sim_agents: np.ndarray) -> np.ndarray:
        return model_agents(scenario, self.request.max_driven)  # valid at the current step: sim agents

    def describe(self) -> dict[str, Any]:
        request = self.request
        return {
            "checkpoint": None if self.checkpoint is None else str(self.checkpoint),
            "prompted_ids": list(self.prompt.mentions) if self.prompt else [],
            "guidance": [f"{t.cost.name}={t.weight:g}" for t in self.terms],
            "candidates": request.candidates,
            "ddim_steps": request.steps,
            "cfg": request.cfg,
            "max_driven": request.max_driven,
            "map_selection": self.data.map_selection,
            "on_road": request.on_road,
            "no_collision": request.no_collision,
            "guided_steps": request.guided_steps,
            "selector": request.selector or self.default_selector(),
            "attention": "dense" if request.dense_attention else "local",
            "prompt_levers": request.levers.names() if self.prompt is not None else [],
            "warm_steps": request.warm_steps,
            "rolling": request.rolling,
            "temperature": request.temperature,
            "refresh_map": request.refresh_map,
            "hard_constraints": None if self.constraints is None else asdict(self.constraints),
            "hold_parked": request.hold_parked,
        }

    # ------------------------------------------------------------------ simulation
    def reset(self, world: SimWorld, seed: int) -> LangTrajRun:
        start = world.scenario_at(0, world.start)
        slots = slots_of(start, world.driven)
        if self.prompt is not None:
            check_prompt_driven(self.prompt, list(slots), self.request.max_driven)
        data = self.data.for_agents(len(world.driven))
        origin = scene_frame(start)
        device = next(self.model.parameters()).device
        scene = GuidanceScene.from_scenario(start, origin, world.driven, num_agents=data.max_agents)
        index = MapIndex.build(start.road_map) if self.prompt_texts else None
        steering = (
            prompt_steering(
                start,
                self.readings,
                world.driven,
                origin,
                self.request.levers,
                index,
                external=external_ids(world),
                routes=world.routes,
            )
            if self.prompt_texts
            else PromptSteering()
        )
        terms = self.terms + self.prompt_terms(world, slots, origin, data.max_agents, steering)
        terms += self.realism_terms(len(world.driven))
        external = tuple(int(slot) for slot in np.flatnonzero(np.isin(world.driven, world.external)))
        judge = CandidateJudge(world, list(steering.asks), index) if index is not None and steering.asks else None
        selector = SELECTORS.create(self.request.selector or self.default_selector(), where="selector")
        here = torch.as_tensor(poses_to_frame(world.current(world.start)[0], origin)[:, :2])
        roads = selector.uses_road or any(isinstance(term.cost, OnRoadCost) for term in terms)
        if roads or self.constraints is not None:
            scene = scene.with_road_field(cover=here)  # built once: every replan's costs sample it
        kept_on_road = None
        if self.constraints is not None:
            vehicles = start.agents.types[world.driven] == int(AgentType.VEHICLE)
            kept_on_road = on_road_vehicles(scene, here.float(), torch.as_tensor(vehicles), external)
        map_arrays = sample_map(start, world.driven, origin, data)
        first = collate_scenes([scene_sample(start, data, agents=world.driven, origin=origin, map_arrays=map_arrays)])
        with torch.no_grad():
            map_context = self.model.encoder.encode_map(first.to(device))
        return LangTrajRun(
            data=data,
            origin=origin,
            map_arrays=map_arrays,
            map_context=map_context,
            scene=scene.to(device),
            terms=terms,
            selector=selector,
            generators=[torch.Generator().manual_seed(seed * 1_000_003 + r) for r in range(world.num_rollouts)],
            prompt=PromptReplans(steering, judge, stagings=self._stagings(steering, origin, slots, index, world)),
            external=external,
            clearance=self.external_terms(len(world.driven), external),
            kept_on_road=None if kept_on_road is None else kept_on_road.to(device),
            held=self.held_slots(start, world, external),
        )

    @staticmethod
    def _stagings(
        steering: PromptSteering, origin: Origin, slots: dict[int, int], index: MapIndex | None, world: SimWorld
    ) -> Stagings | None:
        """The behaviours that start at their trigger (`sim.staging`), or None where none does."""
        if not steering.staged or index is None:
            return None
        start = world.scenario_at(0, world.start)
        keep = {
            k: s
            for k, staged in enumerate(steering.staged)
            if (s := keeping(start, staged.reading, index, origin, slots, world.routes))
        }
        return Stagings(
            steering.staged, origin, slots, index, world.start, started=steering.targets, keep=keep, routes=world.routes
        )

    def held_slots(self, start: Scenario, world: SimWorld, external: tuple[int, ...]) -> tuple[int, ...]:
        """With `hold_parked`, the slots of the driven agents parked in the log (`sim.parked.parked_in_history`:
        judged from the history, never the future) that no prompt names and that are no adversary or target:
        they stand where they are, as the model sees them; otherwise none."""
        if not self.request.hold_parked:
            return ()
        parked = parked_in_history(start)[world.driven]
        named = set(self.prompt.mentions) if self.prompt is not None else set()
        ids = start.agents.ids[world.driven]
        return tuple(
            slot
            for slot in np.flatnonzero(parked).tolist()
            if int(ids[slot]) not in named and slot not in self.free and slot not in external
        )

    def default_selector(self) -> str:
        """`min_guidance` when explicit guidance steers the scene (collision guidance, `--guidance` terms), so that
        selection keeps what it asks for (a per-agent choice would pull an adversary off its target); with a
        prompt, `DEFAULT_SELECTOR` when the selection lever is on (adherence first, then each agent's road and
        collisions), else `min_guidance` when its guidance lever is; otherwise `DEFAULT_SELECTOR`. Every selector
        compares a prompted agent's adherence first when the selection lever is on."""
        if self.terms or self.steers_by_prompt:
            return "min_guidance"
        if self.prompt is not None and not self.request.levers.selection and self.request.levers.guidance:
            return "min_guidance"
        return DEFAULT_SELECTOR

    def realism_terms(self, num_driven: int) -> tuple[GuidanceTerm, ...]:
        """The default guidance on every driven agent: on-road, and no-collision between every pair except
        the agents in `free` (an adversary and its target). The no-collision cost sums its pairs (its "sum"
        reduction, not the paper's mean over the square of the agents involved), so `no_collision` is a fixed
        weight per pair, whatever the scene's size. Both apply at the last `guided_steps` denoising steps."""
        request, when = self.request, self.guided_when
        terms = []
        if request.on_road > 0:
            terms.append(GuidanceTerm(OnRoadCost(), request.on_road, when))
        kept = [slot for slot in range(num_driven) if slot not in self.free]
        if request.no_collision > 0 and len(kept) > 1:
            cost = NoCollisionCost(kept, others=kept, reduction="sum")
            terms.append(GuidanceTerm(cost, request.no_collision, when))
        return tuple(terms)

    def external_terms(self, num_driven: int, external: tuple[int, ...]) -> tuple[GuidanceTerm, ...]:
        """Keep every other driven agent that follows an external agent (an ego under test, which guidance cannot
        steer) `EXTERNAL_BUFFER_M` behind its forecast (`HeadwayCost`), at the denoising steps the realism guidance
        applies at, weighted `external_clearance`; applied by acceleration alone in a step of its own
        (`sim.external.CLEARANCE_ITERATIONS`). Without it the model's agents drive into a braking ego (docs/testing.md,
        'How the other agents react')."""
        others = [slot for slot in range(num_driven) if slot not in external and slot not in self.free]
        weight = self.request.external_clearance
        if not external or not others or weight <= 0:
            return ()
        return tuple(
            GuidanceTerm(HeadwayCost(others, leader, gap=EXTERNAL_BUFFER_M), weight, self.guided_when)
            for leader in external
        )

    @property
    def guided_when(self) -> str | FinalSteps:
        """The denoising steps the realism and clearance guidance apply at: the last `guided_steps` of the `steps`."""
        guided, steps = self.request.guided_steps, self.request.steps
        return "all" if guided == steps else FinalSteps(guided, steps)

    def act(self, world: SimWorld, state: LangTrajRun, step: int, poses: np.ndarray) -> np.ndarray:
        """Staged behaviours started at the step their trigger holds, and scripted agents moved at 10 Hz from the
        scene as it is (`sim.scripted.act`)."""
        if not state.prompt.stagings and not state.prompt.steering.steerings:
            return poses
        dynamics = self.model.dynamics
        if not isinstance(dynamics, Unicycle):
            return poses
        return scripted.act(world, state.prompt, state.origin, dynamics, step, poses)

    def report(self, world: SimWorld, state: LangTrajRun) -> dict[str, Any]:
        """Map coverage: the share of driven agents with a lane point of the model's map within 5 m
        (`model.features.map_coverage`) at the start, and at the simulation's end (mean over rollouts)."""
        ends = {"start": world.start, "end": world.end}
        coverage = {}
        for name, step in ends.items():
            poses = poses_to_frame(world.current(step), state.origin)  # [R, A_d, 4]
            covered = map_coverage(state.map_arrays, poses[..., :2], np.ones(poses.shape[:2], bool))
            coverage[name] = float(covered.mean()) if covered.size else None
        out: dict[str, Any] = {"map_pieces": int(state.map_arrays[1].any(-1).sum()), "map_coverage": coverage}
        if self.prompt is not None:
            out["prompt"] = state.prompt.steering.to_json()
            if state.prompt.stagings:
                out["prompt"]["staged"] = state.prompt.stagings.report(world.num_rollouts)
        if self.prompt_texts:
            out["prompt_warnings"] = list(state.prompt.steering.warnings)
        return out

    def prompt_terms(
        self, world: SimWorld, slots: dict[int, int], origin: Origin, num_agents: int, steering: PromptSteering
    ) -> tuple[GuidanceTerm, ...]:
        """Fixed guidance terms derived from the scene at the start, over `num_agents` model slots (none here:
        the terms toward a prompt's target change with each replan, `steering`; the baseline adds the label
        library's for a prompt whose behaviour was not read)."""
        return ()


@POLICIES.register
class GuidanceBaselinePolicy(LangTrajPolicy):
    """The CTG++-style baseline: the model without text, steered by guidance alone, in place of the loss functions
    an LLM writes for each instruction in CTG++: toward the target the map gives the behaviour read from the
    prompt (`sim.prompts`, `guidance.steering`), or, for a labelled prompt (an InterDrive entry with an interaction
    subtype or single-agent labels) whose reading gives no target, by the label library's terms for its subtype and
    labels (`guidance.library`). A typed prompt is only read: one the reader cannot read is refused, and one whose
    target the map does not give steers by nothing but the realism guidance. Selection keeps what guidance asks
    (`min_guidance`), without judging adherence. Its levers are `GUIDANCE_ONLY`, which it also takes for a request's
    default levers (every lever on, which it cannot honour); it takes no others."""

    name = "guidance_baseline"
    steers_by_prompt = True

    def __init__(
        self, model: LangTraj, data: SampleConfig, request: SimRequest | None = None, *, prompt: PromptEntry, **kwargs
    ):
        request = request or SimRequest()
        if request.levers == ALL_LEVERS:  # the default levers, which the baseline cannot honour: its own instead
            request = replace(request, levers=GUIDANCE_ONLY)
        if request.levers != GUIDANCE_ONLY:
            raise InputError(
                f"the guidance baseline steers by guidance alone (levers {GUIDANCE_ONLY.names()}); it takes no other "
                f"levers, got {request.levers.names()}",
                where="levers",
            )
        # The model runs without the prompt entry (no text; `labelled` keeps it); its text is what the reader reads.
        typed = bool(request.prompts) or not _labelled(prompt)
        request = replace(request, prompts=request.prompts or (prompt.text,))
        super().__init__(model, data, request, typed=typed, **kwargs)
        if not any(reading.read for reading in self.readings) and not _labelled(prompt):
            raise InputError(
                "the guidance baseline needs a prompt whose behaviour it can read, or a labelled one (an InterDrive "
                f"subtype or labels); neither was recognised in {prompt.text!r}",
                where="prompt",
            )
        self.labelled = prompt

    @classmethod
    def from_request(
        cls, scenario: Scenario, request: SimRequest, loaded: LoadedModel | None = None
    ) -> GuidanceBaselinePolicy:
        if len(request.prompts) != 1:
            raise InputError(
                f"the guidance baseline takes exactly one prompt, got {len(request.prompts)}", where="--prompt"
            )
        policy = super().from_request(scenario, request, loaded)
        assert isinstance(policy, GuidanceBaselinePolicy)
        return policy

    def describe(self) -> dict[str, Any]:
        """`prompt_read_as`: the behaviour read (None when not read), and the interaction subtype and labels that
        stand for the prompt: a labelled prompt's own, else those of the behaviour read (`BehaviourSpec`)."""
        reading = next((r for r in self.readings if r.read), None)
        behaviour = None if reading is None else reading.behaviour
        if _labelled(self.labelled) or behaviour is None:
            subtype, labels = self.labelled.subtype, list(self.labelled.labels)
        else:
            subtype, labels = BEHAVIOURS[behaviour].subtype, list(BEHAVIOURS[behaviour].label_keys)
        read = {"behaviour": None if behaviour is None else behaviour.value, "subtype": subtype, "labels": labels}
        return {**super().describe(), "prompted_ids": list(self.labelled.mentions), "prompt_read_as": read}

    def prompt_terms(
        self, world: SimWorld, slots: dict[int, int], origin: Origin, num_agents: int, steering: PromptSteering
    ) -> tuple[GuidanceTerm, ...]:
        if steering.steerings or not _labelled(self.labelled):  # the read behaviour's target steers, if any
            return ()
        mentions = {i: slots[t] for i, t in enumerate(self.labelled.mentions[:2]) if t in slots}
        if 0 not in mentions:
            raise InputError(
                f"the prompt's target agent @{self.labelled.mentions[0]} is not driven by the model", where="prompt"
            )
        current = np.zeros((num_agents, 4))
        current[: len(world.driven)] = poses_to_frame(world.current(world.start)[0], origin)
        state = torch.as_tensor(current, dtype=torch.float32)
        return tuple(
            terms_for_prompt(mentions, state, subtype_id=self.labelled.subtype, label_keys=self.labelled.labels)
        )


def _labelled(prompt: PromptEntry) -> bool:
    """Whether `prompt` carries an InterDrive interaction subtype or single-agent labels (a typed one does not)."""
    return prompt.subtype is not None or bool(prompt.labels)
