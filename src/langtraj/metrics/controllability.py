"""Controllability and safety-critical metrics of rollouts, as the LangTraj paper reports them.

Controllability (the paper's "mADE" column): text conditioning should bring the prompted agents
closer to their logged future, so we measure minADE -- for each prompted agent, the average 2-D
displacement from the logged future, minimised over the rollouts -- with and without conditioning, and
report the relative reduction 1 - conditioned / unconditioned (13.6 % in the paper's Table 1).

Safety-critical simulation (the paper's "Collision Rate" table): one interactive agent is guided to
hit another, so the figure is the fraction of rollouts in which the designated adversary's and
target's boxes touch at some future step. Map adherence and general collisions are reported beside
it as offroad and collision rates over (rollout, agent) pairs.

Geometry is that of WOSAC (`interaction.py`, `road.py`): boxes are rounded rectangles, two objects
collide where their signed distance is below 0, a box is off road where its most off-road corner is
outside the road edge, and box sizes over the whole future are the scenario's at the current step.
Simulated agents are present at every future step, so, unlike the WOSAC rates, collisions and
offroad events count at every step, not only where the log happens to be valid.

Rollouts must fit the scenario under the WOSAC rules (`check_rollouts`): all sim agents, 80 steps.
Steps are indexed 0..79 over the future, step t being scenario step `current_index + 1 + t`.

See docs/metrics.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from langtraj.errors import InputError
from langtraj.metrics.features import COLLISION_THRESHOLD, OFFROAD_THRESHOLD, SceneMap
from langtraj.metrics.interaction import distance_to_nearest_object, pair_signed_distance
from langtraj.metrics.road import distance_to_road_edge
from langtraj.rollouts.container import Rollouts
from langtraj.rollouts.validation import check_rollouts
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import AgentType, StateField

_SHOWN_IDS = 10


def _json_float(value: float) -> float | None:
    """`value` as JSON allows it: NaN and infinities become None (null)."""
    return float(value) if math.isfinite(value) else None


def _id_list(ids: Iterable[int]) -> str:
    values = [int(i) for i in ids]
    shown = ", ".join(str(v) for v in values[:_SHOWN_IDS])
    return shown + (f", ... ({len(values)} in all)" if len(values) > _SHOWN_IDS else "")


def _columns(rollouts: Rollouts, agent_ids: Iterable[int], where: str) -> np.ndarray:
    """Rollout columns of `agent_ids`; unknown or repeated ids raise InputError listing the valid ones."""
    ids = [int(i) for i in agent_ids]
    column = {int(i): c for c, i in enumerate(rollouts.object_id)}
    unknown = [i for i in ids if i not in column]
    if unknown:
        raise InputError(
            f"object ids {_id_list(unknown)} are not rollout agents (valid ids: {_id_list(rollouts.object_id)})",
            where=where,
        )
    repeated = sorted({i for i in ids if ids.count(i) > 1})
    if repeated:
        raise InputError(f"repeated object ids {_id_list(repeated)}", where=where)
    return np.array([column[i] for i in ids], np.int64)


def _current_boxes(scenario: Scenario, tracks: np.ndarray) -> np.ndarray:
    """Length, width and height [A, 3] of `tracks` at the current step: their size over the whole future."""
    fields = [StateField.LENGTH, StateField.WIDTH, StateField.HEIGHT]
    return scenario.agents.states[tracks, scenario.current_index][:, fields].astype(np.float64)


# ---------------------------------------------------------------------------------------------- minADE


@dataclass(frozen=True)
class MinADEResult:
    """minADE of the chosen agents over R rollouts (metres).

    `per_agent[i]` is agent `agent_ids[i]`'s smallest ADE over the rollouts, reached in rollout
    `best_rollout[i]`; `mean` averages `per_agent` (the paper's figure, each agent choosing its own best
    sample); `joint` is the smallest over rollouts of the agents' mean ADE (one rollout for all agents,
    as WOSAC's `min_average_displacement_error`), so `joint >= mean`.
    """

    scenario_id: str
    agent_ids: tuple[int, ...]
    per_agent: tuple[float, ...]
    best_rollout: tuple[int, ...]
    mean: float
    joint: float
    num_rollouts: int

    def to_dict(self) -> dict:
        return {
            "scenario_id": self.scenario_id,
            "agent_ids": list(self.agent_ids),
            "per_agent": [_json_float(v) for v in self.per_agent],
            "best_rollout": list(self.best_rollout),
            "mean": _json_float(self.mean),
            "joint": _json_float(self.joint),
            "num_rollouts": self.num_rollouts,
        }


def average_displacement(scenario: Scenario, rollouts: Rollouts, agent_ids: Sequence[int]) -> np.ndarray:
    """ADE [R, len(agent_ids)]: each rollout's 2-D distance to the logged future, averaged over the log's
    valid future steps.

    Only x and y count: the paper's minADE is a planar displacement, and a rollout's z carries no
    control signal. Steps where the log is invalid (or past the scenario's end) are left out of the
    average, as there is nothing to compare with; an agent without any valid logged future step raises
    InputError, since its displacement is undefined.

    This is not WOSAC's `average_displacement_error`, which is 3-D and averages over the history steps
    too (where the error is 0), so it reads about 80/91 of a future-only figure.
    """
    tracks = check_rollouts(scenario, rollouts)
    cols = _columns(rollouts, agent_ids, "agent_ids")
    if not len(cols):
        raise InputError("no agents to measure", where="agent_ids")
    first = scenario.current_index + 1
    steps = first + np.arange(rollouts.num_steps)
    inside = steps < scenario.num_steps
    steps = np.minimum(steps, scenario.num_steps - 1)
    chosen = tracks[cols]
    log_xy = scenario.agents.states[chosen][:, steps, : StateField.Y + 1].astype(np.float64)  # [E, T, 2]
    log_valid = scenario.agents.valid[chosen][:, steps] & inside  # [E, T]
    counts = log_valid.sum(-1)
    if (counts == 0).any():
        empty = [int(i) for i, n in zip(agent_ids, counts, strict=True) if n == 0]
        raise InputError(
            f"agents {_id_list(empty)} have no valid logged future step in scenario {scenario.scenario_id}, "
            "so their displacement cannot be measured",
            where="agent_ids",
        )
    sim_xy = np.stack([rollouts.x[:, cols], rollouts.y[:, cols]], -1).astype(np.float64)  # [R, E, T, 2]
    err = np.sqrt(((sim_xy - log_xy[None]) ** 2).sum(-1))
    return np.where(log_valid[None], err, 0.0).sum(-1) / counts[None]


def min_ade(scenario: Scenario, rollouts: Rollouts, agent_ids: Sequence[int]) -> MinADEResult:
    """minADE of `agent_ids` (the prompted agents): per agent, the smallest ADE over the rollouts.

    This is the paper's controllability measure; see `average_displacement` for the ADE itself.
    """
    ade = average_displacement(scenario, rollouts, agent_ids)
    best = ade.argmin(axis=0)
    per_agent = ade.min(axis=0)
    return MinADEResult(
        scenario_id=scenario.scenario_id,
        agent_ids=tuple(int(i) for i in agent_ids),
        per_agent=tuple(float(v) for v in per_agent),
        best_rollout=tuple(int(r) for r in best),
        mean=float(per_agent.mean()),
        joint=float(ade.mean(axis=1).min()),
        num_rollouts=rollouts.num_rollouts,
    )


def _reduction(conditioned: float, unconditioned: float) -> float:
    """1 - conditioned / unconditioned; NaN when the unconditioned minADE is 0 (nothing to reduce)."""
    return 1.0 - conditioned / unconditioned if unconditioned > 0 else float("nan")


@dataclass(frozen=True)
class ControllabilityResult:
    """minADE of the prompted agents with and without text conditioning, and the relative reduction.

    `relative_reduction = 1 - min_ade_conditioned / min_ade_unconditioned`: positive when conditioning
    brings the agents closer to the described (logged) behaviour; NaN where the unconditioned minADE is
    0. The `per_agent_*` tuples follow `agent_ids`.
    """

    scenario_id: str
    agent_ids: tuple[int, ...]
    min_ade_conditioned: float
    min_ade_unconditioned: float
    relative_reduction: float
    per_agent_conditioned: tuple[float, ...]
    per_agent_unconditioned: tuple[float, ...]
    per_agent_relative_reduction: tuple[float, ...]

    def to_dict(self) -> dict:
        return {
            "scenario_id": self.scenario_id,
            "agent_ids": list(self.agent_ids),
            "min_ade_conditioned": _json_float(self.min_ade_conditioned),
            "min_ade_unconditioned": _json_float(self.min_ade_unconditioned),
            "relative_reduction": _json_float(self.relative_reduction),
            "per_agent_conditioned": [_json_float(v) for v in self.per_agent_conditioned],
            "per_agent_unconditioned": [_json_float(v) for v in self.per_agent_unconditioned],
            "per_agent_relative_reduction": [_json_float(v) for v in self.per_agent_relative_reduction],
        }


def controllability(
    scenario: Scenario, conditioned: Rollouts, unconditioned: Rollouts, agent_ids: Sequence[int]
) -> ControllabilityResult:
    """Compare the minADE of `agent_ids` in text-conditioned and unconditioned rollouts of one scene."""
    cond = min_ade(scenario, conditioned, agent_ids)
    uncond = min_ade(scenario, unconditioned, agent_ids)
    return ControllabilityResult(
        scenario_id=scenario.scenario_id,
        agent_ids=cond.agent_ids,
        min_ade_conditioned=cond.mean,
        min_ade_unconditioned=uncond.mean,
        relative_reduction=_reduction(cond.mean, uncond.mean),
        per_agent_conditioned=cond.per_agent,
        per_agent_unconditioned=uncond.per_agent,
        per_agent_relative_reduction=tuple(
            _reduction(c, u) for c, u in zip(cond.per_agent, uncond.per_agent, strict=True)
        ),
    )


def pooled_relative_reduction(results: Iterable[ControllabilityResult]) -> float:
    """Dataset-level reduction: 1 - (mean conditioned minADE) / (mean unconditioned minADE) over every
    prompted agent of every scene, each agent weighing the same.

    This is how the paper's figure reads (2.65 m -> 2.29 m is a 13.6 % reduction); averaging the
    per-scene reductions instead would let scenes with a tiny unconditioned minADE dominate.
    """
    cond: list[float] = []
    uncond: list[float] = []
    for r in results:
        cond.extend(r.per_agent_conditioned)
        uncond.extend(r.per_agent_unconditioned)
    if not cond:
        raise InputError("no controllability results to pool")
    return _reduction(float(np.mean(cond)), float(np.mean(uncond)))


# ---------------------------------------------------------------------------------------------- safety


@dataclass(frozen=True)
class PairCollisionResult:
    """Collisions between a designated adversary and its target, per rollout.

    `collision_step[r]` is the first future step (0..79) at which the two boxes touch in rollout `r`,
    or -1; `min_distance[r]` their smallest signed distance over the future (m, negative: overlap).
    """

    scenario_id: str
    adversary_id: int
    target_id: int
    collision_step: tuple[int, ...]
    min_distance: tuple[float, ...]

    @property
    def collided(self) -> tuple[bool, ...]:
        return tuple(s >= 0 for s in self.collision_step)

    @property
    def rate(self) -> float:
        """Fraction of rollouts in which the adversary hits the target: the paper's collision rate."""
        return float(np.mean(self.collided))

    def to_dict(self) -> dict:
        return {
            "scenario_id": self.scenario_id,
            "adversary_id": self.adversary_id,
            "target_id": self.target_id,
            "rate": self.rate,
            "collision_step": list(self.collision_step),
            "min_distance": [_json_float(v) for v in self.min_distance],
        }


def pair_distance(scenario: Scenario, rollouts: Rollouts, adversary_id: int, target_id: int) -> np.ndarray:
    """Signed distance [R, T] between the adversary's and the target's rounded boxes (negative: overlap)."""
    tracks = check_rollouts(scenario, rollouts)
    if int(adversary_id) == int(target_id):
        raise InputError(f"the adversary and the target are the same object {int(adversary_id)}", where="agent_ids")
    cols = _columns(rollouts, [adversary_id, target_id], "adversary/target")
    (la, wa, _), (lb, wb, _) = _current_boxes(scenario, tracks[cols])
    a, b = cols
    return pair_signed_distance(
        rollouts.x[:, a], rollouts.y[:, a], rollouts.heading[:, a], la, wa,
        rollouts.x[:, b], rollouts.y[:, b], rollouts.heading[:, b], lb, wb,
    )  # fmt: skip


def pair_collision(scenario: Scenario, rollouts: Rollouts, adversary_id: int, target_id: int) -> PairCollisionResult:
    """Whether, and when, the adversary's and target's boxes touch (WOSAC distance < 0) in each rollout."""
    dist = pair_distance(scenario, rollouts, adversary_id, target_id)
    hit = dist < COLLISION_THRESHOLD
    first = np.where(hit.any(-1), hit.argmax(-1), -1)
    return PairCollisionResult(
        scenario_id=scenario.scenario_id,
        adversary_id=int(adversary_id),
        target_id=int(target_id),
        collision_step=tuple(int(s) for s in first),
        min_distance=tuple(float(d) for d in dist.min(-1)),
    )


def pair_collision_rate(scenario: Scenario, rollouts: Rollouts, adversary_id: int, target_id: int) -> float:
    """Fraction of rollouts in which the adversary collides with the target at some future step."""
    return pair_collision(scenario, rollouts, adversary_id, target_id).rate


def _agents_or_all(rollouts: Rollouts, agent_ids: Sequence[int] | None) -> np.ndarray:
    cols = np.arange(rollouts.num_agents) if agent_ids is None else _columns(rollouts, agent_ids, "agent_ids")
    if not len(cols):
        raise InputError("no agents to measure", where="agent_ids")
    return cols


def collision_flags(scenario: Scenario, rollouts: Rollouts, agent_ids: Sequence[int] | None = None) -> np.ndarray:
    """bool [R, E]: whether agent `agent_ids[e]` (default: every rollout agent, in rollout order) touches
    any other rollout agent at some future step of rollout r."""
    return _touching(scenario, rollouts, _agents_or_all(rollouts, agent_ids)).any(-1)


@dataclass(frozen=True)
class CollisionEvent:
    """An agent's first contact in a rollout: the rollout, the agent's and its partner's track ids, and the future
    step (0: the first simulated step) at which `collision_flags` first finds it."""

    rollout: int
    agent: int
    other: int
    step: int


def collision_events(scenario: Scenario, rollouts: Rollouts) -> list[CollisionEvent]:
    """Every (rollout, agent) pair `collision_flags` flags, with the step of its first contact and the agent it
    touches then (the deepest: the least signed distance of the same rounded boxes), in rollout then rollout-agent
    order. The one event rule: `sim.failures` and the studio's events build on it."""
    touching = _touching(scenario, rollouts, np.arange(rollouts.num_agents))  # [R, A, T]
    length, width = _boxes(scenario, rollouts)
    pose = [getattr(rollouts, f) for f in ("x", "y", "heading")]
    ids, events = rollouts.object_id, []
    for r, a in zip(*np.nonzero(touching.any(-1)), strict=True):
        step = int(np.argmax(touching[r, a]))
        mine = [float(v[r, a, step]) for v in (*pose, length, width)]
        theirs = [v[r, :, step].astype(np.float64) for v in (*pose, length, width)]
        gap = pair_signed_distance(*(np.full(rollouts.num_agents, m) for m in mine), *theirs)
        gap[a] = np.inf
        events.append(CollisionEvent(int(r), int(ids[a]), int(ids[int(np.argmin(gap))]), step))
    return events


def _boxes(scenario: Scenario, rollouts: Rollouts) -> tuple[np.ndarray, np.ndarray]:
    """Length and width [R, A, T] of the rollout agents: their size at the current step."""
    dims = _current_boxes(scenario, check_rollouts(scenario, rollouts))
    shape = rollouts.x.shape
    return np.broadcast_to(dims[None, :, 0, None], shape), np.broadcast_to(dims[None, :, 1, None], shape)


def _touching(scenario: Scenario, rollouts: Rollouts, cols: np.ndarray) -> np.ndarray:
    """bool [R, E, T]: whether agent column `cols[e]` touches another rollout agent at each future step."""
    length, width = _boxes(scenario, rollouts)
    pose = [getattr(rollouts, f).astype(np.float64) for f in ("x", "y", "heading")]
    dist = distance_to_nearest_object(*pose, length, width, np.ones(rollouts.x.shape, bool), cols)
    return dist < COLLISION_THRESHOLD


def collision_rate(scenario: Scenario, rollouts: Rollouts, agent_ids: Sequence[int] | None = None) -> float:
    """Fraction of (rollout, agent) pairs in which the agent collides with any other rollout agent.

    Default agents: every rollout agent. Pass the evaluated or prompted agents for the experiment tables.
    """
    return float(collision_flags(scenario, rollouts, agent_ids).mean())


def offroad_flags(
    scenario: Scenario,
    rollouts: Rollouts,
    agent_ids: Sequence[int] | None = None,
    *,
    scene_map: SceneMap | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(ids [E], bool [R, E]): whether each agent leaves the road (signed distance to the road edge > 0)
    at some future step of each rollout.

    Default agents: the rollout agents of vehicle type (pedestrians and cyclists legitimately use
    sidewalks). A scene without road edges raises InputError: offroad cannot be measured there.
    """
    ids, first = offroad_first_steps(scenario, rollouts, agent_ids, scene_map=scene_map)
    return ids, first >= 0


def offroad_first_steps(
    scenario: Scenario,
    rollouts: Rollouts,
    agent_ids: Sequence[int] | None = None,
    *,
    scene_map: SceneMap | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """(ids [E], int [R, E]): the first future step (0: the first simulated one) at which each agent is off the
    road in each rollout, -1 where it never is; the agents and errors of `offroad_flags`, which is this >= 0."""
    tracks = check_rollouts(scenario, rollouts)
    if agent_ids is None:
        is_vehicle = scenario.agents.types[tracks] == AgentType.VEHICLE
        cols = np.flatnonzero(is_vehicle)
        if not len(cols):
            raise InputError(f"scenario {scenario.scenario_id} has no vehicle among its rollout agents", where="agents")
    else:
        cols = _agents_or_all(rollouts, agent_ids)
    scene_map = scene_map or SceneMap.from_scenario(scenario)
    if scene_map.road_edges is None:
        raise InputError(
            f"scenario {scenario.scenario_id} has no road edges, so offroad cannot be measured", where="road_map"
        )
    dims = _current_boxes(scenario, tracks[cols])  # [E, 3]
    shape = (rollouts.num_rollouts, len(cols), rollouts.num_steps)
    size = [np.broadcast_to(dims[None, :, k, None], shape) for k in range(3)]
    pose = [getattr(rollouts, f)[:, cols].astype(np.float64) for f in ("x", "y", "z", "heading")]
    off = distance_to_road_edge(scene_map.road_edges, *pose, *size, np.ones(shape, bool)) > OFFROAD_THRESHOLD
    return rollouts.object_id[cols], np.where(off.any(-1), off.argmax(-1), -1)


def agent_rates(
    scenario: Scenario, rollouts: Rollouts, *, scene_map: SceneMap | None = None
) -> tuple[dict[int, float], dict[int, float]]:
    """Per rollout agent (track id), the share of rollouts in which it collides (`collision_flags`), and per
    vehicle the share in which it leaves the road (`offroad_flags`; empty where the map has no road edges or the
    rollouts hold no vehicle)."""
    ids = [int(i) for i in rollouts.object_id]
    collided = dict(zip(ids, collision_flags(scenario, rollouts).mean(axis=0).tolist(), strict=True))
    scene_map = scene_map or SceneMap.from_scenario(scenario)
    types = scenario.agents.types[[scenario.agents.index_of(i) for i in ids]]
    if scene_map.road_edges is None or not (types == AgentType.VEHICLE).any():
        return collided, {}
    found, flags = offroad_flags(scenario, rollouts, scene_map=scene_map)
    return collided, {int(i): float(f) for i, f in zip(found, flags.mean(axis=0), strict=True)}


def offroad_rate(
    scenario: Scenario,
    rollouts: Rollouts,
    agent_ids: Sequence[int] | None = None,
    *,
    scene_map: SceneMap | None = None,
) -> float:
    """Fraction of (rollout, agent) pairs in which the agent goes off road at some future step."""
    return float(offroad_flags(scenario, rollouts, agent_ids, scene_map=scene_map)[1].mean())


@dataclass(frozen=True)
class SafetyResult:
    """The safety-critical table's figures for one scene: adversary-target collisions, plus collision and
    offroad rates over (rollout, agent) pairs; `offroad_rate` is None where the map has no road edges."""

    pair: PairCollisionResult
    collision_rate: float
    offroad_rate: float | None
    num_rollouts: int

    @property
    def pair_collision_rate(self) -> float:
        return self.pair.rate

    def to_dict(self) -> dict:
        return {
            "scenario_id": self.pair.scenario_id,
            "num_rollouts": self.num_rollouts,
            "pair_collision_rate": self.pair.rate,
            "pair": self.pair.to_dict(),
            "collision_rate": _json_float(self.collision_rate),
            "offroad_rate": None if self.offroad_rate is None else _json_float(self.offroad_rate),
        }


def safety(
    scenario: Scenario,
    rollouts: Rollouts,
    adversary_id: int,
    target_id: int,
    agent_ids: Sequence[int] | None = None,
    *,
    scene_map: SceneMap | None = None,
) -> SafetyResult:
    """Every safety figure of one scene's rollouts. `agent_ids` picks the agents of the collision and
    offroad rates (default: all rollout agents for collisions, its vehicles for offroad)."""
    pair = pair_collision(scenario, rollouts, adversary_id, target_id)
    scene_map = scene_map or SceneMap.from_scenario(scenario)
    offroad = (
        offroad_rate(scenario, rollouts, agent_ids, scene_map=scene_map) if scene_map.road_edges is not None else None
    )
    return SafetyResult(
        pair=pair,
        collision_rate=collision_rate(scenario, rollouts, agent_ids),
        offroad_rate=offroad,
        num_rollouts=rollouts.num_rollouts,
    )
