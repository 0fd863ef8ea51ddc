"""An episode's per-step record, the figures summarizing it, and the verdict of a case's criteria on them
(docs/testing.md, 'Scenario suites')."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from langtraj.cases import Criteria

STEP_KEYS = ("collision", "at_fault", "offroad", "ttc", "min_distance", "progress", "progress_m", "speed")
"""The env's step-info figures recorded at every step (`collided_with` and `collisions` are kept too)."""


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
    collided_with: list[list[int]] = field(default_factory=list)
    collisions: list[list[dict[str, Any]]] = field(default_factory=list)

    def add(self, info: dict[str, Any]) -> None:
        """Record one step's info: its flags must be there (a missing one would pass every safety criterion); a
        missing or non-finite figure is recorded as None."""
        for key in ("collision", "at_fault", "offroad"):
            getattr(self, key).append(bool(info[key]))
        for key in ("ttc", "min_distance", "progress", "progress_m", "speed"):
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
    began, the partner (`with`), its `kind` and whether the ego was `at_fault` (`env.fault`), in step order."""
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
    }


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
    return results
