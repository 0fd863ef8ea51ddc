"""`LangTrajEnv`: one ego agent driven by a planner under test, every other agent of a real or synthesized scene
driven closed-loop by LangTraj (prompts, guidance, replanning every second from what the ego actually did), as a
Gymnasium environment (docs/testing.md).

The ego is one of the scene's agents: the model sees it as it sees every other agent, but the ego's motion comes
from the action (`env.dynamics`), and the model's guidance and candidate selection judge the others against a
forecast of the ego (`sim.external`). No simulated agent reads its logged future; only the ego's route is chosen
with the log (`roads.mission`), and `reset`'s info carries the ego's logged future for log-replay baselines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
import torch

from langtraj.angles import wrap_angle
from langtraj.cases import EGO_PLACEHOLDER, Case, read_case
from langtraj.env import spaces
from langtraj.env.dynamics import step_unicycle, track
from langtraj.env.events import EventJudge
from langtraj.env.observe import MapPieces, Observer
from langtraj.env.reward import RewardConfig
from langtraj.env.rules import EpisodeLights, RuleJudge, light_mode
from langtraj.errors import InputError
from langtraj.metrics.road import RoadEdgeIndex, road_edge_index
from langtraj.model.config import ModelConfig
from langtraj.roads import MapIndex
from langtraj.roads.mission import mission_of
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.drivable import measured_road_edges
from langtraj.scenario.io import read_scenario
from langtraj.scenario.model import FUTURE_STEPS, STEP_SECONDS, Scenario
from langtraj.scenario.selection import prioritized_agents
from langtraj.scenario.types import AgentType, StateField
from langtraj.scenario.windowing import nth_window
from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.policies import POLICIES, LoadedModel
from langtraj.sim.prompt_checks import check_prompts
from langtraj.sim.prompts import prompt_mentions
from langtraj.sim.setup import build_policy
from langtraj.sim.stepping import SteppedSimulation
from langtraj.sim.terms import pair_problem

RESET_KEYS = ("scenario", "index", "window", "ego", "prompts", "adversary", "target")
"""The keys of the episode's `Case` that `reset(options=...)` may change."""


@dataclass(frozen=True)
class _Scene:
    """A loaded scene and what is built once per scene, not per episode: its map index, its map cut into
    observation pieces, its road edges (those the metrics and guidance use: `scenario.drivable.measured_road_edges`)."""

    scenario: Scenario
    index: MapIndex = field(repr=False)
    pieces: MapPieces = field(repr=False)
    edges: RoadEdgeIndex | None = field(repr=False)

    @classmethod
    def of(cls, scenario: Scenario) -> _Scene:
        return cls(
            scenario,
            MapIndex.build(scenario.road_map),
            MapPieces.of(scenario),
            road_edge_index([f.points for f in measured_road_edges(scenario)]),
        )


class LangTrajEnv(gym.Env):
    """One ego under a planner's control in a scene every other agent of which LangTraj simulates
    (docs/testing.md). What an episode simulates is a `langtraj.cases.Case`: `case`, its fields replaced by the
    keywords of the same name that are given (scene, ego, prompts, adversary, target; `checkpoint`, default: the
    shipped one), read by `read_case`; `reset(options=...)` may change those of `RESET_KEYS`. The other keywords:
    `policy` of the other agents (a registered `sim.policies.POLICIES` name; "log_replay" reads their logged
    future: a labelled baseline), `action` ("control" or "trajectory", `env.spaces`), `replan_s` (the others'
    replanning interval), `candidates` per replan, `terminate_on_collision` / `terminate_on_offroad`, `reward`
    (`RewardConfig`), `render_mode` ("rgb_array"), and `simulation`: further `sim.config.SimRequest` settings of
    the others' policy (guidance weights, `selector`, ...), `device` the model runs on (e.g. "cuda"; default:
    where it loads, the CPU)."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        scenario: str | Path | Scenario | None = None,
        *,
        index: int | None = None,
        window: int | None = None,
        ego: int | None = None,
        prompts: str | tuple[str, ...] | list[str] | None = None,
        adversary: int | None = None,
        target: int | str | None = None,
        checkpoint: str | Path | None = None,
        case: Case | None = None,
        policy: str = "langtraj",
        action: str = "control",
        replan_s: float = 1.0,
        candidates: int = 4,
        terminate_on_collision: bool = False,
        terminate_on_offroad: bool = False,
        reward: RewardConfig | None = None,
        render_mode: str | None = None,
        simulation: dict[str, Any] | None = None,
        device: str | None = None,
        lights: str = "log",
    ):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InputError(
                f"must be one of {self.metadata['render_modes']} or None, got {render_mode!r}", where="render_mode"
            )
        POLICIES.get(policy, where="policy")
        self.lights = light_mode(lights)
        given = {
            "scenario": scenario,
            "index": index,
            "window": window,
            "ego": ego,
            "prompts": prompts,
            "adversary": adversary,
            "target": target,
            "checkpoint": checkpoint,
        }
        self.case = read_case({k: v for k, v in given.items() if v is not None}, defaults=case)
        self.policy_name = policy
        self.action_kind = action
        self.action_space = spaces.action_space(action)
        self.observation_space = spaces.observation_space()
        self.sim_config = SimConfig(rollouts=1, replan_s=replan_s)
        self.candidates = int(candidates)
        self.simulation = dict(simulation or {})
        unknown = set(self.simulation) - set(SimRequest.__dataclass_fields__) | (
            set(self.simulation) & {"policy", "checkpoint", "prompts", "adversary", "target", "candidates"}
        )
        if unknown:
            raise InputError(f"not a simulation setting here: {', '.join(sorted(unknown))}", where="simulation")
        self.terminate_on_collision = bool(terminate_on_collision)
        self.terminate_on_offroad = bool(terminate_on_offroad)
        self.reward_config = reward or RewardConfig()
        self.render_mode = render_mode
        self.device = device
        self._loaded: LoadedModel | None = None
        self._scenes: dict[tuple[str, int, int | None], _Scene] = {}
        self._sim: SteppedSimulation | None = None

    # ------------------------------------------------------------------ episode
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        episode = read_case(options or {}, where="options", defaults=self.case, keys=RESET_KEYS)
        scene = self._scene(episode)
        scenario = scene.scenario
        ego = ego_row(scenario, episode.ego)
        ego_id = int(scenario.agents.ids[ego])
        prompts = tuple(p.replace(EGO_PLACEHOLDER, f"@{ego_id}") for p in episode.prompts)
        error = check_prompts(scenario, prompts, ego=ego_id, targets=False).first_error()  # the one prompt check
        if error is not None:
            raise InputError(error, where="prompts")
        target = ego_id if episode.target == "ego" else episode.target
        adversary = episode.adversary
        problem = pair_problem(adversary, target, ego=ego_id)  # the scene's own agents: checked by the simulation
        if problem is not None:
            raise InputError(problem[1], where=problem[0])
        request = SimRequest(
            policy=self.policy_name,
            checkpoint=self.case.checkpoint,
            prompts=prompts,
            adversary=adversary,
            target=None if target is None else int(target),
            candidates=self.candidates,
            **self.simulation,
        )
        if self._loaded is None and POLICIES.get(self.policy_name).uses_model:
            from langtraj.model.checkpoint import load_model
            from langtraj.sim.checkpoints import shipped_checkpoint

            model, data = load_model(self.case.checkpoint or shipped_checkpoint())
            self._loaded = (model.to(self.device) if self.device else model, data)
        policy, described = build_policy(scenario, request, self._loaded)
        sim_seed = int(self.np_random.integers(2**31 - 1))
        config = replace(self.sim_config, seed=sim_seed)
        route = mission_of(scenario, ego, scene.index)  # the ego's one route: its planner's, and staging's reading
        self._sim = SteppedSimulation(scenario, policy, np.array([ego]), config, routes={ego_id: route.points})
        self._ego, self._ego_id = ego, ego_id
        logged = _logged_future(scenario, ego)
        seen = logged[np.isfinite(logged[:, 0]), :2]
        self._route = route
        lights = EpisodeLights(scenario, self.lights)
        self._observer = Observer(scenario, ego, self._route, scene.pieces, lights)
        self._judge = EventJudge(scenario, ego, scene.edges, scene.index, lights)
        self._rules = RuleJudge(scenario, ego, scene.index, self._route, lights)
        self._curvature = ego_curvature(scenario, ego)
        self._control = np.zeros(2)
        obs, station = self._observe()
        self._start_station = self._last_station = station
        self._reference_m = (
            max(self._route.station(seen[-1]) - station, 1.0) if len(seen) and self._route.source == "log" else math.nan
        )
        prompted = [i for i in prompt_mentions(scenario, prompts) if i != ego_id]
        self.highlight_ids = [ego_id, *prompted]
        if adversary is not None and adversary not in self.highlight_ids:
            self.highlight_ids.append(int(adversary))
        info = {
            "scenario_id": scenario.scenario_id,
            "ego_id": ego_id,
            "step_seconds": STEP_SECONDS,
            "start_step": scenario.current_index,
            "prompts": list(prompts),
            "prompted_ids": prompted,
            "prompt_warnings": list(self._sim.report().get("prompt_warnings", [])),
            "adversary": adversary,
            "target": target,
            "policy": self.policy_name,
            "sim_seed": sim_seed,
            "driven_ids": described["driven_ids"],
            "route_source": self._route.source,
            "route_length_m": self._route.length,
            "logged_ego": logged,
        }
        return obs, info

    def step(self, action: Any):
        if self._sim is None:
            raise RuntimeError("call reset() before step()")
        if self._sim.done:
            raise RuntimeError("the episode is over (8 s simulated); call reset()")
        pose = self._pose()
        control = self._control_of(action, pose)
        nxt = step_unicycle(pose, control, self._curvature)
        before = self._frame()[0][self._ego].copy()
        self._control = np.array([nxt[3] - pose[3], wrap_angle(nxt[2] - pose[2])]) / STEP_SECONDS  # as executed
        self._sim.advance(nxt[None, None])
        frame = self._frame()
        obs, station = self._observe(frame)
        events = self._judge.judge(*frame, self._sim.step)
        rules = self._rules.judge(before, frame[0][self._ego], self._sim.step, station)
        gained = station - self._last_station
        self._last_station = station
        reward = self.reward_config.reward(gained, events.collision, events.at_fault, events.offroad)
        terminated = (self.terminate_on_collision and events.collision) or (
            self.terminate_on_offroad and events.offroad
        )
        progress_m = station - self._start_station
        info = {
            "step": self._sim.step - self._sim.world.start,
            "time": (self._sim.step - self._sim.world.start) * STEP_SECONDS,
            "collision": events.collision,
            "collided_with": list(events.collided_with),
            "collisions": [c.to_json() for c in events.contacts],
            "at_fault": events.at_fault,
            "offroad": events.offroad,
            "ttc": events.ttc,
            "min_distance": events.min_distance,
            "progress_m": progress_m,
            "progress": progress_m / self._reference_m if math.isfinite(self._reference_m) else math.nan,
            "speed": float(nxt[3]),
            "acceleration": float(self._control[0]),
            "yaw_rate": float(self._control[1]),
            "red_light": rules.red_light,
            "wrong_way": rules.wrong_way,
            "over_speed_limit": rules.over_limit,
        }
        return obs, float(reward), bool(terminated), bool(self._sim.done), info

    # ------------------------------------------------------------------ views
    def played(self) -> Scenario:
        """The episode so far as a scenario: the logged history, then the simulated steps up to now."""
        if self._sim is None:
            raise RuntimeError("call reset() first")
        played = self._sim.world.played(0)
        return played.slice_steps(0, self._sim.step + 1, played.current_index)

    def rollout(self) -> Rollouts:
        """The episode so far as one rollout of every sim agent, the ego included (the studio keeps what it showed)."""
        if self._sim is None:
            raise RuntimeError("call reset() first")
        return self._sim.world.rollouts()

    def simulation_report(self) -> dict[str, Any]:
        """The others' simulation report (`sim.engine`'s: the prompts' targets and warnings among it)."""
        if self._sim is None:
            raise RuntimeError("call reset() first")
        return self._sim.report()

    def render(self) -> np.ndarray | None:
        if self.render_mode is None or self._sim is None:
            return None
        from langtraj.viz.config import RenderConfig
        from langtraj.viz.topdown import TopDownRenderer

        scenario = self.played()
        config = RenderConfig(size_px=512, follow_track_id=self._ego_id, highlight_ids=tuple(self.highlight_ids))
        with TopDownRenderer(scenario, config, steps=[scenario.num_steps - 1]) as renderer:
            return renderer.frame(scenario.num_steps - 1)

    def close(self) -> None:
        self._sim = None

    # ------------------------------------------------------------------ helpers
    def _scene(self, episode: Case) -> _Scene:
        source = episode.scenario
        if source is None:
            raise InputError("no scenario given (a file or a Scenario)", where="scenario")
        name = f"object {id(source)}" if isinstance(source, Scenario) else str(source)
        key = (name, int(episode.index), episode.window)
        if key not in self._scenes:
            scenario = source if isinstance(source, Scenario) else read_scenario(Path(source), int(episode.index))
            if episode.window is not None:
                try:
                    scenario = nth_window(scenario, int(episode.window))
                except InputError as exc:
                    raise exc.located(where=f"{name}: window") from None
            self._scenes = {key: _Scene.of(scenario)}  # the last scene only
        return self._scenes[key]

    def _pose(self) -> np.ndarray:
        assert self._sim is not None
        return self._sim.world.current(self._sim.step, np.array([self._ego]))[0, 0]

    def _frame(self) -> tuple[np.ndarray, np.ndarray]:
        assert self._sim is not None
        world, step = self._sim.world, self._sim.step
        valid = np.zeros(world.valid.shape[1], bool)
        valid[world.sim_agents] = world.valid[0, world.sim_agents, step]
        return world.states[0, :, step], valid

    def _observe(self, frame: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[dict[str, np.ndarray], float]:
        assert self._sim is not None
        states, valid = self._frame() if frame is None else frame
        world, step = self._sim.world, self._sim.step
        elapsed = (step - world.start) * STEP_SECONDS
        first = max(step - spaces.HISTORY_STEPS, 0)
        history = world.states[0, :, first:step], world.valid[0, :, first:step]  # the log's history, then played
        return self._observer.observe(states, valid, elapsed, self._control, history, step)

    def _control_of(self, action: Any, pose: np.ndarray) -> np.ndarray:
        try:
            values = spaces.checked_action(action, self.action_kind)
        except spaces.ActionError as error:
            raise InputError(f"{error} ({self.action_kind} action space)", where="action") from None
        return track(pose, values) if self.action_kind == "trajectory" else values


def ego_row(scenario: Scenario, ego: int | None = None) -> int:
    """The ego's row: the track `ego` (valid at the current step), else the scene's self-driving car, else its most
    important vehicle (the studio asks it too, to refuse a prompt of the ego before a job runs)."""
    sim = sim_agent_indices(scenario)
    if ego is not None:
        try:
            row = scenario.agents.index_of(ego)
        except KeyError:
            raise InputError(f"no agent @{ego} in scenario {scenario.scenario_id}", where="ego") from None
        if row not in set(sim.tolist()):
            raise InputError(f"agent @{ego} is not valid at the scene's current step", where="ego")
        return row
    if scenario.sdc_index >= 0 and scenario.sdc_index in set(sim.tolist()):
        return int(scenario.sdc_index)
    ranked = prioritized_agents(scenario, None)
    vehicles = [r for r in ranked if scenario.agents.types[r] == AgentType.VEHICLE]
    if not vehicles:
        raise InputError(f"scenario {scenario.scenario_id} has no vehicle to be the ego", where="ego")
    return int(vehicles[0])


def _logged_future(scenario: Scenario, row: int) -> np.ndarray:
    """The agent's logged future (x, y, heading, speed) [FUTURE_STEPS, 4], NaN where the log has no state."""
    c = scenario.current_index
    out = np.full((FUTURE_STEPS, 4), np.nan)
    steps = np.arange(c + 1, min(c + 1 + FUTURE_STEPS, scenario.num_steps))
    ok = scenario.agents.valid[row, steps]
    s = scenario.agents.states[row, steps[ok]].astype(np.float64)
    out[steps[ok] - c - 1] = np.stack(
        [
            s[:, StateField.X],
            s[:, StateField.Y],
            s[:, StateField.HEADING],
            np.hypot(s[:, StateField.VX], s[:, StateField.VY]),
        ],
        -1,
    )
    return out


def ego_curvature(scenario: Scenario, row: int) -> float:
    """The ego's tightest turn (1/m): a vehicle's as the model's vehicles of its length turn
    (`ModelConfig.vehicle_curvature`, read at the current step), none for others."""
    if scenario.agents.types[row] != AgentType.VEHICLE:
        return math.inf
    length = float(scenario.agents.states[row, scenario.current_index, StateField.LENGTH])
    return float(ModelConfig().vehicle_curvature(torch.tensor(length)))
