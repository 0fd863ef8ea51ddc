"""Adherence of candidates: whether the future a candidate would give a prompted agent does what it was asked.

At each replan the policy samples several candidates per rollout; for a prompted agent, selection prefers the
candidates that follow its prompt (`sim.selection`, `first`). A candidate's future is the rollout's executed past
followed by the candidate, up to the end of the simulated 8 s, exactly what the judge will read at the end
(`metrics.instruction_following`). Single-agent behaviours are judged by the heuristic labelers themselves, on one
scene holding a copy of the agent per candidate and rollout (one labelling per replan). Pair behaviours are judged by
the interaction detector's own rule for one ordered pair, which each behaviour declares (`BehaviourKind.pair_runs`:
`interdrive.detector.yielding_runs`, `passing_runs`, `following_runs`, `cut_in_runs`, ..., with the judge's
`DetectorConfig`), the one `detect_interactions` runs over every pair, on each candidate's scene: every agent's past
up to the replan, the driven agents' candidates after it, the undriven agents' simulated tracks, speeds from
positions as the judge reads a rollout (`metrics.instruction_following.rollout_scenario`), cut to the agents the rule
reads (`pair_rows`: the two, the vehicles near either that may lead it, and the pedestrians where one of them walks).
Yielding: the prompted agent yields to the other; going first: the other yields to it (the passing side of that
yield); following: it follows the other; cutting in: it changes into the other's lane just ahead of it (overtaking and
cutting in: having been behind it shortly before); braking hard: it brakes hard while the other follows it;
tailgating: it follows the other too closely; running a red light: it passes a red stop line and then crosses the
other's path; pulling out: from (nearly) standing off the other's way, it comes onto it just ahead of it. Each is
judged by its interaction type, whatever the subtype (a prompt read from text names none; the judge of an
experiment's prompt asks for the subtype the log shows), except the last six, judged by their own subtype
(`BehaviourSpec.exact`).

Only simulated states are read: the executed past, the candidates and the undriven agents' simulated tracks (never
the logged future); traffic lights are held at their state at the start of the simulation. See docs/simulation.md
('Prompts that steer').
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from langtraj.interdrive.adherence import label_facts
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour, behaviour_facts
from langtraj.interdrive.behaviours import kind
from langtraj.interdrive.detector import DetectorConfig, SceneGeometry, pair_rows
from langtraj.interdrive.heuristics import HeuristicConfig, label_agents
from langtraj.roads import MapIndex
from langtraj.scenario.model import Agents, Scenario, TrafficLights
from langtraj.scenario.types import StateField
from langtraj.sim.world import SimWorld


@dataclass(frozen=True)
class Ask:
    """What one prompt asks of one driven agent: its scenario `row` and model `slot`, the `behaviour`, for a
    pair behaviour the other agent's row and slot (None when the model does not drive it), and what it does `then`
    (a single-agent behaviour judged with it: "turns left and then stops")."""

    track_id: int
    row: int
    slot: int
    behaviour: Behaviour
    other_id: int | None = None
    other_row: int | None = None
    other_slot: int | None = None
    then: Behaviour | None = None


class CandidateJudge:
    """Judges the candidates of every ask at a replan (see the module docstring); `detector` is the interaction
    detector's settings, the same the judge of instruction following uses (`DetectorConfig()` by default)."""

    def __init__(
        self,
        world: SimWorld,
        asks: list[Ask],
        index: MapIndex,
        config: HeuristicConfig | None = None,
        detector: DetectorConfig | None = None,
    ):
        self.world = world
        self.asks = asks
        self.index = index
        self.config = config or HeuristicConfig()
        self.detector = detector or DetectorConfig()
        self._base = _up_to(replace(world.scenario, traffic_lights=_held_lights(world)), world.end)

    def misses(self, rollouts: list[int], step: int, plans: np.ndarray) -> np.ndarray:
        """bool [len(asks), M, R]: the candidate does not follow the ask. `plans` [M, R, A_d, T, 4] are the
        candidates in the world frame (x, y, heading, speed) for steps step+1 ... of rollouts `rollouts`."""
        out = np.zeros((len(self.asks), *plans.shape[:2]), bool)
        pairs = []
        for k, ask in enumerate(self.asks):
            if not BEHAVIOURS[ask.behaviour].is_pair:
                out[k] = self._single_misses(ask, self._futures(ask.row, ask.slot, rollouts, step, plans))
            elif ask.other_row is not None:
                pairs.append(k)
        if pairs:
            out[pairs] = self._pair_misses([self.asks[k] for k in pairs], rollouts, step, plans)
        return out

    def _futures(self, row: int | None, slot: int | None, rollouts: list[int], step: int, plans: np.ndarray):
        """States [M, R, T_all, 9] of scenario row `row` in each candidate: the rollout's track with the candidate
        written after `step` (an undriven agent keeps its track)."""
        tracks = self.world.states[rollouts, row]  # [R, T_all, 9]
        out = np.repeat(tracks[None], plans.shape[0], axis=0).copy()
        if slot is None:
            return out
        end = self.world.end
        count = min(plans.shape[3], end - step)
        block = out[:, :, step + 1 : step + 1 + count]
        Agents.write_poses(block, plans[:, :, slot, :count].astype(np.float64))
        out[:, :, step + 1 : step + 1 + count] = block
        return out

    def _single_misses(self, ask: Ask, future: np.ndarray) -> np.ndarray:
        """The heuristic labelers on one scene of M x R copies of the agent."""
        m, r = future.shape[:2]
        scenario = self.world.scenario
        count = m * r
        ids = np.arange(count, dtype=np.int64) + 1
        agents = replace(
            scenario.agents,
            ids=ids,
            types=np.repeat(scenario.agents.types[ask.row], count),
            states=future.reshape(count, *future.shape[2:]).astype(np.float32),
            valid=np.ones((count, future.shape[2]), bool),
            tracks_to_predict=np.zeros(0, np.int64),
            prediction_difficulty=None,
            objects_of_interest=np.zeros(0, np.int64),
        )
        copies = replace(scenario, agents=agents, current_index=self.world.start, sdc_index=-1)
        copies = _up_to(copies, self.world.end)
        labels, _ = label_agents(copies, self.config, self.index)
        found = label_facts(labels, ())
        asked = behaviour_facts(ask.behaviour, 0) | (behaviour_facts(ask.then, 0) if ask.then else frozenset())
        wanted = {key for _, _, key in asked}  # type: ignore[misc]
        have: dict[int, set[str]] = {}
        for fact in found:
            have.setdefault(int(fact[1]), set()).add(str(fact[-1]))
        hits = np.array([wanted <= have.get(int(i), set()) for i in ids])
        return ~hits.reshape(m, r)

    def _pair_misses(self, asks: list[Ask], rollouts: list[int], step: int, plans: np.ndarray) -> np.ndarray:
        """bool [len(asks), M, R]: the detector's rule for each ask's interaction type finds no run of the pair in
        the candidate's scene (`candidate_scene`), cut to the agents the rules read (`pair_rows`)."""
        out = np.ones((len(asks), *plans.shape[:2]), bool)
        tracks, valid = self._tracks(rollouts)
        xy = np.repeat(tracks[None, ..., : StateField.Y + 1].astype(np.float64), plans.shape[0], axis=0)
        count = min(plans.shape[3], self.world.end - step)
        driven = self.world.driven
        xy[:, :, driven, step + 1 : step + 1 + count] = plans[:, :, : len(driven), :count, :2]
        types = self._base.agents.types
        for i in range(plans.shape[0]):
            for r in range(len(rollouts)):
                rows = np.unique(
                    np.concatenate(
                        [pair_rows(xy[i, r], valid[r], types, a.row, a.other_row, self.detector) for a in asks]  # type: ignore[arg-type]
                    )
                )
                scenario = self.candidate_scene(tracks[r], valid[r], rows, step, plans[i, r])
                scene = SceneGeometry(scenario, (), self.detector, self.index)
                at = {int(row): k for k, row in enumerate(rows)}
                for k, ask in enumerate(asks):
                    rule = kind(ask.behaviour).pair_runs
                    assert rule is not None, f"pair behaviour {ask.behaviour!s} declares no pair_runs"
                    out[k, i, r] = not rule(scene, at[ask.row], at[ask.other_row])  # type: ignore[index]
        return out

    def _tracks(self, rollouts: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """States [R, A, T, 9] and validity [R, A, T] of every agent of rollouts `rollouts` up to the end of the
        simulated 8 s, agents that are not sim agents hidden after the start (`SimWorld.played`)."""
        world, end = self.world, self.world.end
        tracks = world.states[rollouts][:, :, : end + 1]
        valid = world.valid[rollouts][:, :, : end + 1].copy()
        valid[:, np.setdiff1d(np.arange(valid.shape[1]), world.sim_agents), world.start + 1 :] = False
        return tracks, valid

    def candidate_scene(
        self, tracks: np.ndarray, valid: np.ndarray, rows: np.ndarray, step: int, plan: np.ndarray
    ) -> Scenario:
        """The scene of scenario rows `rows` up to the end of the simulated 8 s as the judge will read the rollout
        of `tracks` [A, T, 9] and `valid` [A, T] (`_tracks`), had candidate `plan` [A_d, T, 4] been executed at
        `step`: every agent's past up to `step`, the driven agents' candidate after it (their earlier plans where
        it is shorter), the undriven agents' simulated tracks; speeds from positions over the simulated steps
        (`rollout_scenario`); traffic lights as at the start."""
        world, start, end = self.world, self.world.start, self.world.end
        states = tracks[rows].copy()  # [K, T, 9]
        slots = np.full(tracks.shape[0], -1, np.int64)
        slots[world.driven] = np.arange(len(world.driven))
        slot = slots[rows]
        moved = np.flatnonzero(slot >= 0)
        count = min(plan.shape[1], end - step)
        block = states[moved, step + 1 : step + 1 + count]
        Agents.write_poses(block, plan[slot[moved], :count].astype(np.float64))
        states[moved, step + 1 : step + 1 + count] = block
        sim = np.isin(rows, world.sim_agents)
        xy = states[sim, start : end + 1, : StateField.Y + 1].astype(np.float64)
        dt = np.diff(self._base.timestamps[start : end + 1])
        speed = np.linalg.norm(np.diff(xy, axis=1), axis=-1) / np.maximum(dt, 1e-6)
        block = states[sim, start + 1 : end + 1]
        heading = block[..., StateField.HEADING].astype(np.float64)
        Agents.write_poses(block, np.concatenate([xy[:, 1:], heading[..., None], speed[..., None]], -1), wrap=False)
        states[sim, start + 1 : end + 1] = block
        base = self._base
        agents = replace(
            base.agents,
            ids=base.agents.ids[rows],
            types=base.agents.types[rows],
            states=states,
            valid=valid[rows],
            tracks_to_predict=np.zeros(0, np.int64),
            prediction_difficulty=None,
            objects_of_interest=np.zeros(0, np.int64),
        )
        return replace(base, agents=agents, sdc_index=-1)


def _held_lights(world: SimWorld) -> TrafficLights:
    """The world's traffic lights with every step after the start showing the lights as held at the start
    (`TrafficLights.held_at`; the logged future of the lights is not read)."""
    lights = world.scenario.traffic_lights
    assert lights is not None
    states, valid = lights.states.copy(), lights.valid.copy()
    states[world.start + 1 :], valid[world.start + 1 :] = lights.held_at(world.start)
    return replace(lights, states=states, valid=valid)


def _up_to(scenario: Scenario, end: int) -> Scenario:
    """The scenario cut after step `end` (the simulated 8 s)."""
    if scenario.num_steps <= end + 1:
        return scenario
    agents = replace(
        scenario.agents, states=scenario.agents.states[:, : end + 1], valid=scenario.agents.valid[:, : end + 1]
    )
    lights = scenario.traffic_lights
    if lights is not None:
        lights = replace(lights, states=lights.states[: end + 1], valid=lights.valid[: end + 1])
    return replace(scenario, agents=agents, timestamps=scenario.timestamps[: end + 1], traffic_lights=lights)
