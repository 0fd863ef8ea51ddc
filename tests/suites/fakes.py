"""A fake of `langtraj.env.LangTrajEnv` with the same interface, whose scene file (JSON) says what happens, and
planners that misbehave in the scene called "bad" only (so that a suite's other case passes with them)."""

from __future__ import annotations

import json
import os
import re
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from langtraj.cases import Case
from langtraj.env.spaces import action_space, observation_space
from langtraj.errors import InputError

TESTS_DIR = Path(__file__).resolve().parents[1]
FAKE_ENV = "suites.fakes:FakeEnv"
"""The fake's "module:Class" (tests/ is on sys.path, in spawned workers too)."""


def write_scene(folder: Path, name: str, **behaviour: Any) -> Path:
    """A fake scene file: `scenario_id` = `name`; keys: steps (80), collide_at, collided_with ([7]), at_fault,
    contact (the collisions' own keys over the default front or rear, e.g. kind and right_of_way), offroad_at, ttc
    (5.0), min_ttc_at ([step, value]), progress (final fraction, 1.0), error_at (the env raises), exit_at (the process
    dies), agents (the track ids a prompt may name, checked by `FakeEnv.check_case`; none: any), refuse_at_reset (a
    message: reset raises it as an InputError at "prompt", as the sim refuses a prompt only the model can), traffic
    (what the other agents do in `played`: a list of `{"move": ID, "at": STEP, "onto": ID, "dx": M, "dy": M}`, the
    agent placed from that step on at `onto`'s centre (default: its own) shifted by dx, dy; given, the toy scene has
    five vehicles, 7 to 47, all valid)."""
    path = folder / f"{name}.json"
    path.write_text(json.dumps({"scenario_id": name, **behaviour}))
    return path


def _observation() -> dict[str, np.ndarray]:
    return {key: np.zeros(space.shape, space.dtype) for key, space in observation_space().spaces.items()}


class FakeEnv:
    """Same constructor, reset, step, played, highlight_ids and close as LangTrajEnv."""

    built: list[dict[str, Any]] = []  # noqa: RUF012 -- what each construction was given (in-process runs)

    def __init__(
        self,
        scenario: Any = None,
        *,
        case: Case | None = None,
        action: str = "control",
        terminate_on_collision: bool = False,
        terminate_on_offroad: bool = False,
        render_mode: str | None = None,
    ):
        case = case or Case(scenario=scenario)
        index, ego, prompts, adversary, target = case.index, case.ego, case.prompts, case.adversary, case.target
        self.data = json.loads(Path(case.scenario).read_text())
        if self.data.get("error_at") == 0:
            raise InputError("the fake scene cannot be built", where="scenario")
        self.kind = action
        self.ego = 17 if ego is None else ego  # a track of the toy scene `played` returns
        self.prompts = [p.replace("@ego", f"@{self.ego}") for p in prompts]
        self.adversary = adversary
        self.target = self.ego if target == "ego" else target
        self.terminate_on_collision = terminate_on_collision
        self.highlight_ids = [self.ego] + ([adversary] if adversary is not None else [])
        FakeEnv.built.append({"index": index, "ego": ego, "prompts": list(prompts), "target": target})
        self.k = 0

    @staticmethod
    def check_case(case: Case) -> None:
        """The suite's pre-flight (`suites.preflight`): a prompt naming an agent not in the scene's `agents`."""
        agents = json.loads(Path(case.scenario).read_text()).get("agents")
        for j, prompt in enumerate(case.prompts):
            for mention in re.findall(r"@(\d+)", prompt):
                if agents is not None and int(mention) not in agents:
                    raise InputError(f"unknown agent @{mention}; the scene has agents {agents}", where=f"prompts[{j}]")

    def reset(self, *, seed: int | None = None, options: Any = None):
        if self.data.get("refuse_at_reset"):
            raise InputError(self.data["refuse_at_reset"], where="prompt")
        self.k = 0
        info = {
            "scenario_id": self.data["scenario_id"],
            "ego_id": self.ego,
            "step_seconds": 0.1,
            "prompted_ids": [],
            "prompts": self.prompts,
            "adversary": self.adversary,
            "target": self.target,
            "logged_ego": np.full((80, 4), np.nan),
        }
        return _observation(), info

    def step(self, action: Any):
        a = np.asarray(action, dtype=np.float64)
        if a.shape != action_space(self.kind).shape or not np.isfinite(a).all():
            raise InputError("bad action", where="action")
        self.k += 1
        d, k = self.data, self.k
        if d.get("error_at") == k:
            raise RuntimeError("the fake env broke")
        if d.get("exit_at") == k:
            os._exit(3)  # the worker process dies
        collision = d.get("collide_at") is not None and k >= d["collide_at"]
        steps = d.get("steps", 80)
        ttc = d.get("ttc", 5.0)
        if d.get("min_ttc_at") and d["min_ttc_at"][0] == k:
            ttc = d["min_ttc_at"][1]
        info = {
            "step": k,
            "time": k * 0.1,
            "collision": collision,
            "collided_with": d.get("collided_with", [7]) if collision else [],
            "collisions": [
                {
                    "with": i,
                    "kind": "front" if d.get("at_fault") else "rear",
                    "at_fault": bool(d.get("at_fault")),
                    **d.get("contact", {}),
                }
                for i in (d.get("collided_with", [7]) if collision else [])
            ],
            "at_fault": collision and d.get("at_fault", False),
            "offroad": d.get("offroad_at") is not None and k >= d["offroad_at"],
            "ttc": ttc,
            "min_distance": 3.0,
            "progress_m": k * 1.0,
            "progress": d.get("progress", 1.0) * k / steps,
            "speed": 10.0,
        }
        terminated = self.terminate_on_collision and collision
        return _observation(), 0.0, bool(terminated), k >= steps, info

    def played(self):
        sys.path.insert(0, str(TESTS_DIR))
        from scenario_builders import make_scenario

        traffic = self.data.get("traffic")
        if traffic is None:
            return make_scenario(num_steps=11 + self.k, scenario_id=self.data["scenario_id"])
        return with_traffic(make_scenario(5, 11 + self.k, scenario_id=self.data["scenario_id"]), traffic)

    def close(self) -> None:
        pass


def with_traffic(scene: Any, moves: list[dict[str, Any]]) -> Any:
    """The toy `scene` with every agent a valid vehicle, each of `moves` applied (`write_scene`'s traffic)."""
    from langtraj.scenario.types import AgentType

    agents = scene.agents
    states, ids = agents.states.copy(), [int(i) for i in agents.ids]
    for move in moves:
        row, onto = ids.index(move["move"]), ids.index(move.get("onto", move["move"]))
        later = slice(scene.current_index + move["at"], None)
        states[row, later, :2] = states[onto, later, :2] + [move.get("dx", 0.0), move.get("dy", 0.0)]
    types = np.full(len(ids), int(AgentType.VEHICLE), np.int8)
    changed = replace(agents, states=states, valid=np.ones_like(agents.valid), types=types)
    return replace(scene, agents=changed)


class GoodPlanner:
    """Drives straight on (zero control) everywhere; the misbehaving planners below derive from it."""

    action_kind = "control"

    def reset(self, observation: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        self.bad = info["scenario_id"] == "bad"
        self.k = 0

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        self.k += 1
        return self.misbehave(self.k) if self.bad else np.zeros(2, np.float32)

    def misbehave(self, k: int) -> Any:
        return np.zeros(2, np.float32)


class RaisingPlanner(GoodPlanner):
    def misbehave(self, k: int) -> Any:
        if k == 3:
            raise ValueError("boom\nsecond line")
        return np.zeros(2)


class NaNPlanner(GoodPlanner):
    def misbehave(self, k: int) -> Any:
        return np.array([np.nan, 0.0]) if k == 12 else np.zeros(2)


class WrongShapePlanner(GoodPlanner):
    def misbehave(self, k: int) -> Any:
        return np.zeros(3)


class HangingPlanner(GoodPlanner):
    def misbehave(self, k: int) -> Any:
        if k == 2:
            time.sleep(60)
        return np.zeros(2)


class SwallowingHangPlanner(GoodPlanner):
    """Hangs in a busy loop and catches every Exception: the step limit must still end it."""

    def misbehave(self, k: int) -> Any:
        while True:
            try:  # noqa: SIM105 -- the point: a planner that swallows every Exception
                time.sleep(0.01)
            except Exception:
                pass


class OneArgumentPlanner:
    """A duck-typed planner whose reset takes the observation only, answering trajectories."""

    action_kind = "trajectory"

    def reset(self, observation: dict[str, np.ndarray]) -> None:
        pass

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        return np.zeros((10, 3), np.float32)


class BadKindPlanner(GoodPlanner):
    action_kind = "teleport"
