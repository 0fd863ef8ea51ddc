"""The CTG++-style "LLM guidance" baseline: a fixed library of guidance terms per InterDrive label.

CTG++ has an LLM write a differentiable loss for each instruction. InterDrive's vocabulary is fixed, so
the paper generated one function per interaction description and per heuristic label and scaled the
losses to a common range (appendix 'LLM-Based Guidance Details'). This library is that table, written
out once: every interaction subtype id and single-agent label key maps to a builder that turns the
agents a prompt mentions (and their current states) into `GuidanceTerm`s.

Common range: each weight divides its cost by the size of a clear violation (2 m/s of speed error, 1 m
off a lane centre or over a road margin, 5 m from a goal, a full disk overlap), so a clear violation of
any term costs about 1.

See docs/simulation.md.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Literal

import torch
from torch import Tensor

from langtraj.errors import InputError
from langtraj.guidance.base import GuidanceTerm
from langtraj.guidance.costs import CollisionCost, GoalCost, KeepLaneCost, NoCollisionCost, OnRoadCost, TargetSpeedCost
from langtraj.interdrive.prompts.compose import OTHER_PREFIX, TARGET, Prompt
from langtraj.interdrive.targets import SPEED_CHANGE
from langtraj.interdrive.taxonomy import LANE_POSITIONS, label_def
from langtraj.scenario import FUTURE_STEPS

SPEED_WEIGHT = 1 / 2.0**2
LANE_WEIGHT = 1.0
ROAD_WEIGHT = 1.0
GOAL_WEIGHT = 1 / 5.0
AVOID_WEIGHT = 4.0  # one ordered pair among N = 2 agents: no_collision is its mean overlap / 4
PULL_WEIGHT = 1 / 20.0  # collision (mean centre distance, m) used to close a gap

WALKING_SPEED = 1.2  # m/s
SLOW_SPEED = 2.0  # m/s, "moving slowly"
TURN_RADIUS = 10.0  # m, of the quarter circle a turn goal lies on
LANE_WIDTH = 3.5  # m, the lateral offset of a lane-change goal

Part = Literal["all", "first", "second"]
"""Which part of the horizon a term covers: all of it, or its first or second half."""


@dataclass(frozen=True)
class PromptAgents:
    """What a builder sees: the slots of the prompt's target agent and of the other agent (None when the
    prompt names none or it is not simulated), the current states [A, 4] (x, y, heading, speed; scene
    frame), the rollout horizon (`num_steps` of `dt` s) and the label's parameters."""

    target: int
    other: int | None
    current_state: Tensor
    num_steps: int = FUTURE_STEPS
    dt: float = 0.1
    params: Mapping[str, str] = field(default_factory=dict)

    @property
    def horizon(self) -> float:
        """Seconds covered by the rollout."""
        return self.num_steps * self.dt

    def speed(self) -> float:
        return float(self.current_state[self.target, 3])

    def other_speed(self) -> float:
        """The other agent's speed, or the target's own when there is no other agent."""
        return self.speed() if self.other is None else float(self.current_state[self.other, 3])

    def point(self, forward: float, left: float) -> tuple[float, float]:
        """The scene-frame point `forward` m ahead of and `left` m to the left of the target's current pose."""
        x, y, heading = (float(v) for v in self.current_state[self.target, :3])
        c, s = math.cos(heading), math.sin(heading)
        return x + forward * c - left * s, y + forward * s + left * c

    def window(self, part: Part) -> tuple[int, int | None]:
        """The steps [start, end) of `part` of the horizon (end None: to its end)."""
        half = self.num_steps // 2
        return {"all": (0, None), "first": (0, half), "second": (half, None)}[part]


Builder = Callable[[PromptAgents], list[GuidanceTerm]]
SpeedRule = Callable[[PromptAgents], float]


# ---------------------------------------------------------------- building blocks


def _all(*builders: Builder) -> Builder:
    return lambda a: [term for build in builders for term in build(a)]


def _none(agents: PromptAgents) -> list[GuidanceTerm]:
    """No cost expresses the behaviour: only the model's own prior acts."""
    return []


def _speed(rule: SpeedRule, part: Part = "all") -> Builder:
    def build(a: PromptAgents) -> list[GuidanceTerm]:
        start, end = a.window(part)
        return [GuidanceTerm(TargetSpeedCost(a.target, max(rule(a), 0.0), start=start, end=end), SPEED_WEIGHT)]

    return build


def _lane(part: Part = "all") -> Builder:
    def build(a: PromptAgents) -> list[GuidanceTerm]:
        start, end = a.window(part)
        return [GuidanceTerm(KeepLaneCost(a.target, start=start, end=end), LANE_WEIGHT)]

    return build


def _road(agents: PromptAgents) -> list[GuidanceTerm]:
    return [GuidanceTerm(OnRoadCost(agents.target), ROAD_WEIGHT)]


def _avoid(buffer: float) -> Builder:
    """Keep clear of the other agent by `buffer` m beyond touching."""

    def build(a: PromptAgents) -> list[GuidanceTerm]:
        if a.other is None:
            return []
        return [GuidanceTerm(NoCollisionCost(a.target, others=a.other, buffer=buffer), AVOID_WEIGHT)]

    return build


def _pull(agents: PromptAgents) -> list[GuidanceTerm]:
    """Close the gap to the other agent (with `_avoid`, an equilibrium close behind it)."""
    if agents.other is None:
        return []
    return [GuidanceTerm(CollisionCost(agents.target, agents.other), PULL_WEIGHT)]


def _own(factor: float = 1.0, add: float = 0.0, low: float = 0.0) -> SpeedRule:
    return lambda a: max(a.speed() * factor + add, low)


def _fixed(speed: float) -> SpeedRule:
    return lambda a: speed


def _other(a: PromptAgents) -> float:
    return a.other_speed()


def _faster(add: float) -> SpeedRule:
    return lambda a: max(a.speed(), a.other_speed()) + add


def _slower(a: PromptAgents) -> float:
    return min(a.speed(), a.other_speed())


def _turn(side: int) -> Builder:
    """A goal on a quarter circle of `TURN_RADIUS` to the left (side 1) or right (-1), continued straight,
    as far along as the current speed (at least 8 m) carries the agent over the horizon."""

    def build(a: PromptAgents) -> list[GuidanceTerm]:
        travel = max(a.speed() * a.horizon, 8.0)
        quarter = math.pi / 2 * TURN_RADIUS
        if travel <= quarter:
            angle = travel / TURN_RADIUS
            forward, left = TURN_RADIUS * math.sin(angle), TURN_RADIUS * (1 - math.cos(angle))
        else:
            forward, left = TURN_RADIUS, TURN_RADIUS + travel - quarter
        return [GuidanceTerm(GoalCost(a.target, a.point(forward, side * left)), GOAL_WEIGHT)]

    return build


def _straight(agents: PromptAgents) -> list[GuidanceTerm]:
    """A goal straight ahead, at least walking speed times the horizon away."""
    forward = max(agents.speed(), WALKING_SPEED) * agents.horizon
    return [GuidanceTerm(GoalCost(agents.target, agents.point(forward, 0.0)), GOAL_WEIGHT)]


def _change_lanes(agents: PromptAgents) -> list[GuidanceTerm]:
    """End in a lane; with `from`/`to` lane positions (leftmost < middle < rightmost), also a goal one
    lane width to that side."""
    terms = _lane("second")(agents)
    order = {p: i for i, p in enumerate(LANE_POSITIONS[:3])}
    start, end = order.get(agents.params.get("from", "")), order.get(agents.params.get("to", ""))
    if start is not None and end is not None and start != end:
        side = 1.0 if end < start else -1.0
        forward = max(agents.speed() * agents.horizon, 10.0)
        terms.append(GuidanceTerm(GoalCost(agents.target, agents.point(forward, side * LANE_WIDTH)), GOAL_WEIGHT))
    return terms


def _pull_over(agents: PromptAgents) -> list[GuidanceTerm]:
    """Stop in the second half of the horizon, on the road, at a goal half a lane width to the right (the kerb
    side in right-hand traffic), as far ahead as braking evenly over the first half carries the agent (at
    least 5 m)."""
    forward = max(agents.speed() * agents.horizon / 4, 5.0)
    goal = GuidanceTerm(GoalCost(agents.target, agents.point(forward, -LANE_WIDTH / 2)), GOAL_WEIGHT)
    return [goal, *_speed(_fixed(0.0), "second")(agents), *_road(agents)]


# ---------------------------------------------------------------- the library

INTERACTION_GUIDANCE: Mapping[str, Builder] = MappingProxyType(
    {
        # Lane changes: end the manoeuvre in a lane, clear of the other agent.
        "lane_change/for_turn_or_exit": _all(_lane("second"), _avoid(1.0)),
        "lane_change/for_overtaking": _all(_lane("second"), _avoid(1.0), _speed(_faster(2.0), "second")),
        "lane_change/avoiding_slower_traffic": _all(_lane("second"), _avoid(1.0), _speed(_faster(2.0), "second")),
        "lane_change/for_merging": _all(_lane("second"), _avoid(1.5), _speed(_other)),
        "lane_change/with_lead_or_trail": _all(_lane("second"), _avoid(2.0)),
        "lane_change/cut_in": _all(_lane("second"), _avoid(1.0), _speed(_other)),
        # Following: stay in lane a gap behind the lead, at its speed (or stopping).
        "following/with_lead": _all(_lane(), _avoid(2.0), _speed(_other)),
        "following/slow_lead": _all(_lane(), _avoid(2.0), _speed(_slower)),
        "following/tailgating": _all(_lane(), _avoid(0.3), _pull, _speed(_other)),
        "following/stopping_behind_lead": _all(_lane(), _avoid(2.0), _speed(_fixed(0.0), "second")),
        "following/stopping_behind_intersection": _all(_lane(), _speed(_fixed(0.0), "second")),
        # Yielding: slow down (or wait) in the first half while the other agent passes, keeping clear.
        "yielding/intersection": _all(_avoid(3.0), _speed(_own(0.3), "first")),
        "yielding/before_merge_or_lane_change": _all(_avoid(3.0), _speed(_own(0.5), "first")),
        "yielding/to_merging_or_lane_change": _all(_lane(), _avoid(3.0), _speed(_own(0.5), "first")),
        "yielding/to_pedestrian": _all(_avoid(3.0), _speed(_fixed(0.0), "first")),
        "yielding/roundabout": _all(_avoid(3.0), _speed(_own(0.3), "first")),
        "yielding/pedestrian_to_vehicle": _all(_avoid(2.0), _speed(_fixed(0.0), "first")),
        # Passing: keep going (without yielding), clear of the other agent.
        "passing/intersection_with_yielding": _all(_lane(), _avoid(1.0), _speed(_own(low=3.0))),
        "passing/pedestrian": _all(_lane(), _avoid(1.5), _speed(_own())),
        "passing/pedestrian_passing_vehicle": _all(_avoid(1.0), _speed(_own(low=WALKING_SPEED))),
        "passing/roundabout": _all(_lane(), _avoid(1.0), _speed(_own(low=3.0))),
        "passing/maintaining_speed": _speed(_own()),
        "passing/as_leading_vehicle": _all(_lane(), _avoid(1.0), _speed(_own())),
        "passing/braking_lead": _all(_lane(), _speed(_fixed(0.0), "second")),
        "passing/red_light_running": _all(_lane(), _avoid(1.0), _speed(_own(low=8.0))),
        "passing/vru_crossing": _all(_avoid(1.0), _speed(_own(low=WALKING_SPEED))),
        # Overtaking: faster than the other agent, clear of it, back in a lane at the end.
        "overtaking/car_avoidance": _all(_road, _avoid(1.5)),
        "overtaking/standard": _all(_lane("second"), _avoid(1.0), _speed(_faster(3.0))),
        "overtaking/high_speed": _all(_lane("second"), _avoid(1.5), _speed(_faster(5.0))),
        "overtaking/cut_in": _all(_lane("second"), _avoid(1.0), _speed(_faster(3.0), "first")),
        # Merging: join the other agent's stream at its speed, clear of it.
        "merging/standard": _all(_lane("second"), _avoid(1.5), _speed(_other)),
        "merging/lane_reduction": _all(_road, _lane("second"), _avoid(1.5), _speed(_other)),
        "merging/zipper": _all(_lane("second"), _avoid(1.0), _speed(_other)),
        "merging/on_ramp_accelerating": _all(_lane("second"), _avoid(1.5), _speed(_faster(0.0), "second")),
        "merging/late": _all(_lane("second"), _avoid(1.0)),
        "merging/pull_out": _all(_lane("second"), _avoid(1.0), _speed(_own(low=5.0), "second")),
        # Other: nothing to steer towards.
        "other/undefined": _none,
        "other/no_interaction": _none,
        "other/unknown": _none,
    }
)
"""Interaction subtype id (`taxonomy.Subtype.id`) -> builder of the target agent's terms."""

LABEL_GUIDANCE: Mapping[str, Builder] = MappingProxyType(
    {
        "parked": _speed(_fixed(0.0)),
        "off_main_road": _none,  # no map cost tells a main road from a side one
        "static": _speed(_fixed(0.0)),
        "moving_slowly": _speed(_fixed(SLOW_SPEED)),
        "speeding_up": _speed(_own(add=SPEED_CHANGE), "second"),
        "slowing_down": _speed(_own(add=-SPEED_CHANGE), "second"),
        "constant_speed": _speed(_own()),
        "turning_right": _turn(-1),
        "turning_left": _turn(1),
        "going_straight": _lane(),
        "crossing_intersection": _all(_lane(), _speed(_own(low=3.0))),
        "approaching_intersection": _all(_lane(), _speed(_own())),
        "lane_position": _lane(),
        "changing_lanes": _change_lanes,
        "pulling_over": _pull_over,
        "crossing_street": _all(_straight, _speed(_own(low=WALKING_SPEED))),
        "walking_along_road": _speed(_own(low=WALKING_SPEED)),
        "moving": _speed(_own(low=1.0)),
    }
)
"""Single-agent label key (`taxonomy.SINGLE_AGENT_LABELS`) -> builder of that agent's terms."""


# ---------------------------------------------------------------- entry points

_ROLES: Mapping[int | str, str] = {
    0: "target",
    "target": "target",
    TARGET: "target",
    1: "other",
    "other": "other",
    f"{OTHER_PREFIX}1": "other",
}


def terms_for_prompt(
    mentions: Mapping[int | str, int],
    current_state: Tensor,
    *,
    subtype_id: str | None = None,
    label_keys: Sequence[str] = (),
    label_params: Mapping[str, Mapping[str, str]] | None = None,
    num_steps: int = FUTURE_STEPS,
    dt: float = 0.1,
) -> list[GuidanceTerm]:
    """The library's terms for one prompt: its interaction `subtype_id` (if any) and its `label_keys`.

    `mentions` maps roles to model slots: the prompt's target agent as 0, "target" or "the target agent",
    the other agent as 1, "other" or "other agent1" (it may be left out: terms about it are dropped).
    `current_state` is [A, 4] (x, y, heading, speed) in the scene frame; `label_params` holds the
    parameters of labels that take them (e.g. {"changing_lanes": {"from": "middle", "to": "leftmost"}});
    the horizon is `num_steps` steps of `dt` s. Unknown roles, subtypes or labels raise InputError.
    """
    roles: dict[str, int] = {}
    for key, value in mentions.items():
        if key not in _ROLES:
            raise InputError(f"unknown role {key!r} in mentions; known: {', '.join(map(repr, _ROLES))}")
        roles[_ROLES[key]] = int(value)
    if "target" not in roles:
        raise InputError(f"mentions name no target agent: {dict(mentions)}")
    state = torch.as_tensor(current_state).detach().cpu()
    if state.ndim != 2 or state.shape[1] != 4:
        raise InputError(f"current_state must be [A, 4], got {tuple(state.shape)}")
    for role, index in roles.items():
        if not 0 <= index < state.shape[0]:
            raise InputError(f"{role} slot {index} is out of range for {state.shape[0]} agents")
    builders: list[tuple[Builder, Mapping[str, str]]] = []
    if subtype_id is not None:
        if subtype_id not in INTERACTION_GUIDANCE:
            raise InputError(f"unknown interaction subtype {subtype_id!r}")
        builders.append((INTERACTION_GUIDANCE[subtype_id], {}))
    for key in label_keys:
        label_def(key)
        builders.append((LABEL_GUIDANCE[key], dict((label_params or {}).get(key, {}))))
    terms: list[GuidanceTerm] = []
    for build, params in builders:
        agents = PromptAgents(roles["target"], roles.get("other"), state, num_steps, dt, params)
        terms += build(agents)
    return terms


def terms_for(
    prompt: Prompt,
    slot_of_track: Mapping[int, int],
    current_state: Tensor,
    *,
    label_params: Mapping[str, Mapping[str, str]] | None = None,
    num_steps: int = FUTURE_STEPS,
    dt: float = 0.1,
) -> list[GuidanceTerm]:
    """`terms_for_prompt` for a composed `Prompt`: its first mention is the target agent, its second the
    other; `slot_of_track` maps track ids to model slots (an unsimulated other agent is dropped)."""
    if not prompt.mentions or prompt.mentions[0] not in slot_of_track:
        raise InputError(f"the target agent of prompt {prompt.text!r} is not among the simulated agents")
    mentions = {i: slot_of_track[track] for i, track in enumerate(prompt.mentions[:2]) if track in slot_of_track}
    return terms_for_prompt(
        mentions,
        current_state,
        subtype_id=prompt.subtype_id,
        label_keys=prompt.label_keys,
        label_params=label_params,
        num_steps=num_steps,
        dt=dt,
    )
