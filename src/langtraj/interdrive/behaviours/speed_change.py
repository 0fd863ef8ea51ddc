"""Speeding up or slowing down: the way ahead at `SPEED_CHANGE` more or less, judged by the labelers' speed labels.
See docs/interdrive.md ('Targets and feasibility')."""

from __future__ import annotations

from collections.abc import Mapping

from langtraj.interdrive.behaviour import Behaviour, BehaviourSpec
from langtraj.interdrive.behaviours.base import BehaviourKind, Steer, register, route, speed, steps
from langtraj.interdrive.reader.words import OBJ, POSSESSIVE, verb
from langtraj.interdrive.targets.context import SPEED_CHANGE, AgentHere, TargetContext
from langtraj.interdrive.targets.target import BehaviourTarget, TargetUnavailable

# ---------------------------------------------------------------------------------------------- words

_SPEED_UP = [
    rf"\b{verb('speed')}{OBJ}\s+up\b",
    rf"\b{verb('accelerate')}\b(?!\s+(?:away\s+from|to\s+avoid)\b)",
    rf"\b{verb('pick')}\s+up\s+(?:the\s+|some\s+)?(?:speed|pace|tempo|momentum)\b",
    rf"\b{verb('gain', 'gather', 'build', 'build up')}\s+(?:some\s+|more\s+)?(?:speed|pace|momentum)\b",
    rf"\b{verb('hit', 'press', 'floor', 'stamp on', 'step on', 'push', 'mash', 'open up')}\s+(?:the|its|your|their)"
    r"\s+(?:accelerator|gas(?:\s+pedal)?|throttle)\b",
    rf"\b(?:{verb('increase', 'raise')}|up(?:s|ped|ping)?)\s+(?:{POSSESSIVE}\s+|some\s+)?(?:speed|pace)\b",
    rf"\b{verb('step')}\s+on\s+(?:it|the\s+(?:gas|accelerator|throttle))\b",
    rf"\b{verb('put')}\s+(?:{POSSESSIVE}|the)\s+foot\s+down\b|\b{verb('floor', 'gun')}\s+it\b",
    rf"\b{verb('hurry')}(?:\s+up)?\b|\b{verb('get')}\s+a\s+move\s+on\b",
    r"\b(?:faster|quicker|more\s+quickly)\b",
    rf"\b{verb('quicken')}\s+(?:{POSSESSIVE}\s+)?pace\b",
]

_SLOW_DOWN = [
    rf"\b{verb('slow')}(?:{OBJ}\s+(?:down|up))?\b",
    rf"\b{verb('decelerate', 'brake')}\b",
    rf"\b{verb('hit', 'tap', 'touch', 'use', 'apply', 'press', 'step on')}\s+(?:the|its|your|their)\s+brakes?\b",
    rf"\b{verb('ease', 'back')}\s+(?:off|up|back)\b"
    r"(?:\s+(?:on\s+|off\s+)?(?:the\s+)?(?:throttle|gas|accelerator|pedal|pace|speed))?",
    rf"\b{verb('come', 'get', 'lift', 'back', 'let')}\s+off\s+(?:the\s+)?(?:throttle|gas|accelerator|pedal)\b",
    rf"\b{verb('lose', 'reduce', 'drop', 'cut', 'lower', 'decrease', 'shed', 'bleed off', 'bring down', 'lessen')}"
    rf"\s+(?:{POSSESSIVE}\s+|some\s+|a\s+bit\s+of\s+|a\s+little\s+|some\s+of\s+{POSSESSIVE}\s+)?(?:speed|pace)\b",
    rf"\b{verb('take')}\s+it\s+(?:easy|slow|slower)\b",
    r"\b(?:slower|more\s+slowly)\b",
]

# ---------------------------------------------------------------------------------------------- target


def _speed_change(ctx: TargetContext, agent: AgentHere, behaviour: Behaviour) -> BehaviourTarget:
    """The way ahead at 3 m/s more or less (slowing down keeps at least 35 % of the speed; it needs the agent to
    move)."""
    v = agent.here.speed
    if behaviour is Behaviour.SLOW_DOWN and not ctx.moving(agent):
        raise TargetUnavailable(agent.track_id, behaviour, "infeasible", "it is (nearly) stopped at the current step")
    speed = v + SPEED_CHANGE if behaviour is Behaviour.SPEED_UP else max(v - SPEED_CHANGE, 0.35 * v)
    return BehaviourTarget(
        agent.track_id, behaviour, ctx.ahead(agent), f"its way ahead at {speed:.1f} m/s", speed=speed,
        current_speed=v,
    )  # fmt: skip


class _SpeedChange(BehaviourKind):
    def target(
        self, ctx: TargetContext, agent: AgentHere, other: AgentHere | None, asked: Mapping[str, float]
    ) -> BehaviourTarget:
        return _speed_change(ctx, agent, Behaviour(self.name))

    def steer(self, target: BehaviourTarget, other_driven: bool) -> list[Steer]:
        """The target speed from 3 s on, along its lane."""
        return speed(float(target.speed or 0.0), steps(3.0)) + route(weight=0.25)


@register
class SpeedUp(_SpeedChange):
    """Speeding up."""

    name = "speed_up"
    spec = BehaviourSpec(Behaviour.SPEED_UP, "@{agent} speeds up", "speed up", "speeding_up")
    words = tuple(_SPEED_UP)
    word_rank = 9


@register
class SlowDown(_SpeedChange):
    """Slowing down."""

    name = "slow_down"
    spec = BehaviourSpec(Behaviour.SLOW_DOWN, "@{agent} slows down", "slow down", "slowing_down")
    words = tuple(_SLOW_DOWN)
    word_rank = 10
