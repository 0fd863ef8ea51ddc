"""An episode's per-step record, the figures summarizing it, and the verdict of a case's criteria on them
(docs/testing.md, 'Scenario suites')."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import Any

from langtraj.cases import Criteria
from langtraj.scenario.model import STEP_SECONDS

STEP_KEYS = (
    "collision", "at_fault", "offroad", "ttc", "min_distance", "progress", "progress_m", "speed", "acceleration",
    "yaw_rate", "red_light", "wrong_way", "over_speed_limit",
)  # fmt: skip
"""The env's step-info figures recorded at every step (`collided_with` and `collisions` are kept too)."""
_RULE_FLAGS = ("red_light", "wrong_way")
"""Flags an env may not report (None where missing: a criterion on them then says it was not measured)."""
_FIGURES = ("ttc", "min_distance", "progress", "progress_m", "speed", "acceleration", "yaw_rate", "over_speed_limit")

COMFORT_BOUNDS = {
    "min_acceleration": -4.05,
    "max_acceleration": 2.40,
    "max_abs_jerk": 4.13,
    "max_abs_yaw_rate": 0.95,
    "max_abs_lateral_acceleration": 4.89,
}
"""nuPlan's `ego_is_comfortable` bounds (m/s^2, m/s^3, rad/s); here on the executed controls, without nuPlan's
smoothing: the jerk is the change of acceleration between successive 0.1-s steps."""


@dataclass
class StepRecord:
    """The env's figures at every step taken, in order (step k+1 at position k)."""

    collision: list[bool] = field(default_factory=list)
    at_fault: list[bool] = field(default_factory=list)
    offroad: list[bool] = field(default_factory=list)
    ttc: list[float | None] = field(default_factory=list)
    min_distance: list[float | None] = field(default_factory=list)
    progress: list[float | None] = field(default_factory=list)
    progress_m: list[float | None] = field(default_factory=list)
    speed: list[float | None] = field(default_factory=list)
    acceleration: list[float | None] = field(default_factory=list)
    yaw_rate: list[float | None] = field(default_factory=list)
    red_light: list[bool | None] = field(default_factory=list)
    wrong_way: list[bool | None] = field(default_factory=list)
    over_speed_limit: list[float | None] = field(default_factory=list)
    collided_with: list[list[int]] = field(default_factory=list)
    collisions: list[list[dict[str, Any]]] = field(default_factory=list)

    def add(self, info: dict[str, Any]) -> None:
        """Record one step's info: its flags must be there (a missing one would pass every safety criterion); a
        missing or non-finite figure is recorded as None."""
        for key in ("collision", "at_fault", "offroad"):
            getattr(self, key).append(bool(info[key]))
        for key in _RULE_FLAGS:
            getattr(self, key).append(None if info.get(key) is None else bool(info[key]))
        for key in _FIGURES:
            getattr(self, key).append(_number(info.get(key)))
        self.collided_with.append([int(i) for i in info.get("collided_with", ()) or ()])
        self.collisions.append([dict(c) for c in info.get("collisions", ()) or ()])

    @property
    def steps(self) -> int:
        return len(self.collision)

    def to_json(self) -> dict[str, list]:
        return {key: list(getattr(self, key)) for key in (*STEP_KEYS, "collided_with", "collisions")}


def _number(value: Any) -> float | None:
    """A finite float, or None for a missing or non-finite value (JSON has no NaN)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _first(flags: list[bool]) -> int | None:
    """The 1-based step of the first true flag."""
    return next((k + 1 for k, flag in enumerate(flags) if flag), None)


def _rounded(value: float | None, digits: int = 4) -> float | None:
    return None if value is None else round(value, digits)


def contacts(record: StepRecord) -> list[dict[str, Any]]:
    """Every collision of the episode, whether or not it fails a criterion: the step each contact with a partner
    began, the partner (`with`), its `kind`, whether the ego was `at_fault` (`env.fault`) and, where right of way
    decided it, `right_of_way` (signal, sign or lanes: `env.right_of_way.Basis`), in step order."""
    out, before = [], set()
    for k, step in enumerate(record.collisions):
        now = {c["with"]: c for c in step}
        out += [{"step": k + 1, **now[p]} for p in now if p not in before]
        before = set(now)
    return out


def episode_figures(record: StepRecord) -> dict[str, Any]:
    """The episode in figures: `steps`; `collisions` (`contacts`); `first_collision_step` and `collided_with` (the
    track ids hit then),
    `first_at_fault_step` and `at_fault_with`, `first_offroad_step` and `offroad_steps` (None / [] / 0 when it
    never happened); `min_ttc` (s) with `min_ttc_step`, `min_distance` (m), `final_progress` (fraction of the
    logged ego's progress), `final_progress_m`, `mean_speed` and `max_speed` (m/s); None where no step measured
    it."""
    collision = _first(record.collision)
    at_fault = _first(record.at_fault)
    ttcs = [(t, k + 1) for k, t in enumerate(record.ttc) if t is not None]
    min_ttc = min(ttcs, default=(None, None))
    distances = [d for d in record.min_distance if d is not None]
    speeds = [s for s in record.speed if s is not None]
    return {
        "steps": record.steps,
        "collision": collision is not None,
        "collisions": contacts(record),
        "first_collision_step": collision,
        "collided_with": record.collided_with[collision - 1] if collision else [],
        "at_fault_collision": at_fault is not None,
        "first_at_fault_step": at_fault,
        "at_fault_with": record.collided_with[at_fault - 1] if at_fault else [],
        "offroad": any(record.offroad),
        "first_offroad_step": _first(record.offroad),
        "offroad_steps": sum(record.offroad),
        "min_ttc": _rounded(min_ttc[0]),
        "min_ttc_step": min_ttc[1],
        "min_distance": _rounded(min(distances, default=None)),
        "final_progress": _rounded(record.progress[-1] if record.progress else None),
        "final_progress_m": _rounded(record.progress_m[-1] if record.progress_m else None),
        "mean_speed": _rounded(sum(speeds) / len(speeds) if speeds else None),
        "max_speed": _rounded(max(speeds, default=None)),
        **_rule_figures(record),
        **comfort_figures(record),
    }


def _rule_figures(record: StepRecord) -> dict[str, Any]:
    """Red lights, driving direction and speed limit (None where the env did not report them)."""
    out: dict[str, Any] = {}
    for key in _RULE_FLAGS:
        flags = getattr(record, key)
        known = [f for f in flags if f is not None]
        out[f"first_{key}_step"] = _first([bool(f) for f in flags]) if known else None
        out[f"{key}_steps"] = sum(known) if known else None
    over = [v for v in record.over_speed_limit if v is not None]
    out["max_over_speed_limit"] = _rounded(max(over, default=None))
    return out


def comfort_figures(record: StepRecord) -> dict[str, Any]:
    """The extremes of the ego's executed acceleration, jerk, yaw rate and lateral acceleration, and whether all lie
    within `COMFORT_BOUNDS` (`comfortable`; None without steps)."""
    accel = [a for a in record.acceleration if a is not None]
    yaw = [w for w in record.yaw_rate if w is not None]
    lateral = [
        abs(w * v) for w, v in zip(record.yaw_rate, record.speed, strict=True) if w is not None and v is not None
    ]
    jerk = [abs(b - a) / STEP_SECONDS for a, b in itertools.pairwise(accel)]
    out = {
        "min_acceleration": min(accel, default=None),
        "max_acceleration": max(accel, default=None),
        "max_abs_jerk": max(jerk, default=None),
        "max_abs_yaw_rate": max((abs(w) for w in yaw), default=None),
        "max_abs_lateral_acceleration": max(lateral, default=None),
    }
    if not accel:
        return {k: None for k in out} | {"comfortable": None}
    return {k: _rounded(v) for k, v in out.items()} | {"comfortable": not comfort_breaches(out)}


def comfort_breaches(figures: dict[str, Any]) -> list[str]:
    """The comfort figures outside `COMFORT_BOUNDS`, one "key value (bound b)" each (none known: none)."""
    return [
        f"{key} {figures[key]:g} (bound {bound:g})"
        for key, bound in COMFORT_BOUNDS.items()
        if figures[key] is not None and (figures[key] < bound if key.startswith("min_") else figures[key] > bound)
    ]


@dataclass(frozen=True)
class CriterionResult:
    """One criterion's verdict: its `name` (a key of `Criteria`), whether it `passed`, the measured `value`, the
    `limit` it was held to (None for the yes/no criteria) and, when it failed, the one-line `reason`."""

    name: str
    passed: bool
    value: Any
    limit: float | None = None
    reason: str | None = None

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "passed": self.passed,
            "value": self.value,
            "limit": self.limit,
            "reason": self.reason,
        }


def _ids(ids: list[int]) -> str:
    return ", ".join(str(i) for i in ids) or "an unknown agent"


def judge(criteria: Criteria, figures: dict[str, Any]) -> list[CriterionResult]:
    """The verdict of each criterion the case checks (`episode_figures` gives `figures`), in `Criteria` order."""
    results = []
    if criteria.no_at_fault_collision:
        step = figures["first_at_fault_step"]
        reason = f"at-fault collision with {_ids(figures['at_fault_with'])} at step {step}" if step else None
        results.append(CriterionResult("no_at_fault_collision", step is None, step is not None, reason=reason))
    if criteria.no_collision:
        step = figures["first_collision_step"]
        reason = f"collision with {_ids(figures['collided_with'])} at step {step}" if step else None
        results.append(CriterionResult("no_collision", step is None, step is not None, reason=reason))
    if criteria.no_offroad:
        step = figures["first_offroad_step"]
        reason = f"offroad at step {step} ({figures['offroad_steps']} steps in all)" if step else None
        results.append(CriterionResult("no_offroad", step is None, step is not None, reason=reason))
    if criteria.min_ttc is not None:
        value = figures["min_ttc"]
        passed = value is None or value >= criteria.min_ttc  # no step measured it: nothing was ever close
        reason = None if passed else f"min TTC {value:.2f} s < {criteria.min_ttc:g} s at step {figures['min_ttc_step']}"
        results.append(CriterionResult("min_ttc", passed, value, criteria.min_ttc, reason))
    if criteria.min_progress is not None:
        value = figures["final_progress"]
        passed = value is not None and value >= criteria.min_progress
        if passed:
            reason = None
        elif value is None:
            reason = "progress not measured (no steps, or the logged ego does not move)"
        else:
            reason = f"progress {value:.2f} < {criteria.min_progress:g} of the logged ego's"
        results.append(CriterionResult("min_progress", passed, value, criteria.min_progress, reason))
    for key, words in (("red_light", "ran a red light"), ("wrong_way", "drove against its lane")):
        if getattr(criteria, f"no_{key}"):
            steps, first = figures[f"{key}_steps"], figures[f"first_{key}_step"]
            if steps is None:
                reason = f"{key.replace('_', ' ')} not measured (the env did not report it)"
            else:
                reason = f"{words} at step {first} ({steps} steps in all)" if first else None
            results.append(CriterionResult(f"no_{key}", steps == 0, steps, reason=reason))
    if criteria.max_over_speed_limit is not None:
        value, limit = figures["max_over_speed_limit"], criteria.max_over_speed_limit
        passed = value is None or value <= limit  # no limit known along the way: nothing to break
        reason = None if passed else f"{value:.1f} m/s over the speed limit (allowed {limit:g})"
        results.append(CriterionResult("max_over_speed_limit", passed, value, limit, reason))
    if criteria.comfortable:
        passed = figures["comfortable"] is True
        outside = comfort_breaches(figures)
        reason = None if passed else ("uncomfortable: " + ", ".join(outside) if outside else "comfort not measured")
        results.append(CriterionResult("comfortable", passed, figures["comfortable"], reason=reason))
    return results
