"""Adherence of candidates: whether the future a candidate would give a prompted agent does what it was asked.

At each replan the policy samples several candidates per rollout; for a prompted agent, selection prefers the
candidates that follow its prompt (`sim.selection`, `first`). A candidate's future is the rollout's executed
past followed by the candidate, up to the end of the simulated 8 s, exactly what the judge will read at the end
(`metrics.instruction_following`). Single-agent behaviours are judged by the heuristic labelers themselves, on
one scene holding a copy of the agent per candidate and rollout (one labelling per replan). Pair behaviours are
judged by the interaction detector's rule for a yield at the crossing point of the two agents' paths (the one
that comes second held back before it while the other is near; going first: the other yields), and by staying
behind for following.

Only simulated states are read: the executed past and the candidates (never the logged future).
See docs/simulation.md ('Prompts that steer').
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from langtraj.angles import wrap_angle
from langtraj.interdrive.adherence import label_facts
from langtraj.interdrive.behaviour import BEHAVIOURS, Behaviour, behaviour_facts
from langtraj.interdrive.detector import DetectorConfig
from langtraj.interdrive.heuristics import HeuristicConfig, label_agents
from langtraj.interdrive.mapindex import MapIndex
from langtraj.scenario.model import STEP_SECONDS, Agents, Scenario
from langtraj.scenario.types import AgentType, StateField
from langtraj.sim.world import SimWorld

CROSSING_RADIUS = 2.0
"""Two positions this close (m), at more than `CROSSING_ANGLE` to each other, are the same crossing point."""
CROSSING_ANGLE = np.radians(20.0)
HELD_SPEED = DetectorConfig().held_speed
"""A yielding vehicle is held (at or below this speed, m/s) somewhere before the crossing point."""
STANDING_SPEED = DetectorConfig().stopped_speed
"""A yielding pedestrian or cyclist stands (at or below this speed, m/s) somewhere before the crossing point."""
FOE_HORIZON_S = DetectorConfig().foe_horizon_s
"""The passing agent counts while at most this far, in time at its speed, from the crossing point (s)."""
YIELD_MIN_STEPS = DetectorConfig().min_event_steps
"""A yield holds for at least this many steps."""
PASSING_HALF_LENGTH = 2.25
"""Half a car's length: the passing agent is at the crossing point while its centre is this much beyond the radius."""
WAIT_EXTENSION = 10.0
"""A yielding agent that never reaches the crossing is extended straight this far (m), as the detector does."""


@dataclass(frozen=True)
class Ask:
    """What one prompt asks of one driven agent: its scenario `row` and model `slot`, the `behaviour`, and for a
    pair behaviour the other agent's row and slot (None when the model does not drive it)."""

    track_id: int
    row: int
    slot: int
    behaviour: Behaviour
    other_id: int | None = None
    other_row: int | None = None
    other_slot: int | None = None


class CandidateJudge:
    """Judges the candidates of every ask at a replan (see the module docstring)."""

    def __init__(self, world: SimWorld, asks: list[Ask], index: MapIndex, config: HeuristicConfig | None = None):
        self.world = world
        self.asks = asks
        self.index = index
        self.config = config or HeuristicConfig()

    def misses(self, rollouts: list[int], step: int, plans: np.ndarray) -> np.ndarray:
        """bool [len(asks), M, R]: the candidate does not follow the ask. `plans` [M, R, A_d, T, 4] are the
        candidates in the world frame (x, y, heading, speed) for steps step+1 ... of rollouts `rollouts`."""
        out = np.zeros((len(self.asks), *plans.shape[:2]), bool)
        for k, ask in enumerate(self.asks):
            future = self._futures(ask.row, ask.slot, rollouts, step, plans)  # [M, R, T_all, 9]
            if not BEHAVIOURS[ask.behaviour].is_pair:
                out[k] = self._single_misses(ask, future)
            elif ask.other_slot is not None or ask.other_row is not None:
                other = self._futures(ask.other_row, ask.other_slot, rollouts, step, plans)
                out[k] = self._pair_misses(ask, future, other)
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
        wanted = {key for _, _, key in behaviour_facts(ask.behaviour, 0)}  # type: ignore[misc]
        have: dict[int, set[str]] = {}
        for fact in found:
            have.setdefault(int(fact[1]), set()).add(str(fact[-1]))
        hits = np.array([wanted <= have.get(int(i), set()) for i in ids])
        return ~hits.reshape(m, r)

    def _pair_misses(self, ask: Ask, mine: np.ndarray, theirs: np.ndarray) -> np.ndarray:
        """Order at the crossing point (going first, yielding) or staying behind (following), per candidate."""
        start, end = self.world.start + 1, self.world.end + 1
        a = mine[:, :, start:end]
        b = theirs[:, :, start:end]
        out = np.ones(a.shape[:2], bool)
        types = self.world.scenario.agents.types
        held = [_held_speed(int(types[ask.row])), _held_speed(int(types[ask.other_row]))]  # type: ignore[index]
        for i in range(a.shape[0]):
            for j in range(a.shape[1]):
                out[i, j] = not _follows(ask.behaviour, a[i, j], b[i, j], held)
        return out


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


def _pose(track: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    xy = track[:, [StateField.X, StateField.Y]].astype(np.float64)
    heading = track[:, StateField.HEADING].astype(np.float64)
    speed = np.hypot(track[:, StateField.VX], track[:, StateField.VY])
    return xy, heading, speed


def _held_speed(agent_type: int) -> float:
    return HELD_SPEED if agent_type == AgentType.VEHICLE else STANDING_SPEED


def _follows(behaviour: Behaviour, mine: np.ndarray, theirs: np.ndarray, held: list[float]) -> bool:
    """Whether track `mine` [T, 9] does `behaviour` toward track `theirs` [T, 9] over the simulated steps; `held`
    is the speed at or below which each of the two waits (`_held_speed` of its type)."""
    xa, ha, va = _pose(mine)
    xb, hb, vb = _pose(theirs)
    if behaviour is Behaviour.FOLLOW:
        gap = xb - xa
        ahead = gap[:, 0] * np.cos(ha) + gap[:, 1] * np.sin(ha)
        side = np.abs(-gap[:, 0] * np.sin(ha) + gap[:, 1] * np.cos(ha))
        aligned = np.abs(wrap_angle(hb - ha)) < np.radians(30.0)
        behind = (ahead > 0) & (ahead < 40.0) & (side < 2.5) & aligned
        return bool(behind.mean() >= 0.5)
    forward = np.array([np.cos(ha[-1]), np.sin(ha[-1])])
    extension = xa[-1] + np.arange(1.0, WAIT_EXTENSION + 0.5, 1.0)[:, None] * forward[None]
    path = np.concatenate([xa, extension])
    heading = np.concatenate([ha, np.full(len(extension), ha[-1])])
    gaps = np.linalg.norm(path[:, None] - xb[None], axis=-1)  # [T + E, T]
    crossing = (gaps < CROSSING_RADIUS) & (np.abs(wrap_angle(heading[:, None] - hb[None])) > CROSSING_ANGLE)
    rows = np.flatnonzero(crossing.any(axis=1))
    if not rows.size:
        return False
    point = path[int(rows[0])]  # the first point of my path that the other's path crosses
    if behaviour is Behaviour.GO_FIRST:  # first there, while the other is held back before it (it yields)
        return _waits_for(xb, vb, held[1], xa, va, point)
    return _waits_for(xa, va, held[0], xb, vb, point)


def _waits_for(
    waiting: np.ndarray, wait_speed: np.ndarray, held: float, passing: np.ndarray, pass_speed: np.ndarray, point
) -> bool:
    """The detector's yield (`detector.yields.YieldGeometry._yield_mask`) on two tracks' positions [T, 2] and speeds
    [T]: the passing agent gets to `point` first, and the waiting one is held back (at or below `held`, or braking)
    for at least `YIELD_MIN_STEPS` steps before it gets there while the passing one is near it (inside, or moving
    and at most `FOE_HORIZON_S` away at its speed)."""
    steps = np.arange(len(waiting))
    at_waiting = np.flatnonzero(np.linalg.norm(waiting - point, axis=1) < CROSSING_RADIUS)
    reach = int(at_waiting[0]) if at_waiting.size else len(waiting)
    distance = np.linalg.norm(passing - point, axis=1)
    inside = distance < CROSSING_RADIUS + PASSING_HALF_LENGTH
    if not inside.any() or int(np.flatnonzero(inside)[0]) > reach:
        return False
    last_in = int(np.flatnonzero(inside)[-1])
    approaching = (distance / np.maximum(pass_speed, 1.0) <= FOE_HORIZON_S) & (pass_speed > held)
    braking = np.gradient(wait_speed) / STEP_SECONDS < DetectorConfig().braking
    holding = ((wait_speed <= held) | braking) & (steps <= last_in) & (approaching | inside) & (steps < reach)
    return int(holding.sum()) >= YIELD_MIN_STEPS
