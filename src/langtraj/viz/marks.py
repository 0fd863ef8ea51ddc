"""Target marks: where a prompt asks an agent to go, drawn on the map of a top-down frame.

A `TargetMark` is a few world-frame points and a kind: `path` (a dashed polyline in the highlight colour),
`stop` (one point: an octagon; two points: the ends of a stop bar), `goal` (a star at each point) or
`conflict` (a cross at each point), with an optional short label. `RenderConfig.marks` takes them;
`marks_from_prompt` makes them from a simulation summary's `prompt` report (the targets the map gives the
behaviours read from the typed prompts, `interdrive.targets.BehaviourTarget.to_json`). This module reads
that JSON only, so viz does not depend on the simulator.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from langtraj.errors import InputError
from langtraj.viz import style

MARK_KINDS = ("path", "stop", "goal", "conflict")
"""What a mark draws: a dashed path, a stop (octagon or bar), a goal star, a conflict cross."""

MAX_LABEL_CHARS = 60
"""Longest label a mark takes (one line beside the mark)."""

SAME_POINT_M = 1.0
"""A goal this close to its target's conflict point is the conflict point (marked once, as the conflict)."""


def _point(value: Any, field: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"{field} must be two numbers (x, y), got {value!r}", where="TargetMark") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise InputError(f"{field} must be finite, got ({x!r}, {y!r})", where="TargetMark")
    return x, y


@dataclass(frozen=True)
class TargetMark:
    """World-frame points (metres) drawn on the map under the agents; see the module docstring for `kind`."""

    points: tuple[tuple[float, float], ...]
    kind: str = "path"
    label: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in MARK_KINDS:
            raise InputError(f"kind must be one of {', '.join(MARK_KINDS)}, got {self.kind!r}", where="TargetMark")
        if isinstance(self.points, str | bytes) or not isinstance(self.points, Sequence | np.ndarray):
            raise InputError(f"points must be a sequence of (x, y), got {self.points!r}", where="TargetMark")
        points = tuple(_point(p, f"points[{k}]") for k, p in enumerate(self.points))
        least, most = {"path": (2, None), "stop": (1, 2), "goal": (1, None), "conflict": (1, None)}[self.kind]
        if len(points) < least or (most is not None and len(points) > most):
            wanted = {"path": "at least two", "stop": "one (an octagon) or two (a bar)"}.get(self.kind, "at least one")
            raise InputError(
                f"points of a {self.kind} mark must be {wanted} (x, y), got {len(points)}", where="TargetMark"
            )
        if self.label is not None and (
            not isinstance(self.label, str) or "\n" in self.label or len(self.label) > MAX_LABEL_CHARS
        ):
            raise InputError(
                f"label must be one line of at most {MAX_LABEL_CHARS} characters or None, got {self.label!r}",
                where="TargetMark",
            )
        object.__setattr__(self, "points", points)

    @property
    def xy(self) -> np.ndarray:
        """The points as an array [N, 2]."""
        return np.asarray(self.points, np.float64).reshape(-1, 2)


def stop_bar(path: np.ndarray, at: np.ndarray, length_m: float = style.MARK_STOP_BAR_M) -> np.ndarray | None:
    """The ends [2, 2] of a bar `length_m` long across `path` [N, 2] at its point nearest `at` [2]; None where the
    path gives no direction there."""
    if len(path) < 2:
        return None
    k = int(np.argmin(np.linalg.norm(path - at, axis=1)))
    d = path[min(k + 1, len(path) - 1)] - path[max(k - 1, 0)]
    norm = float(np.hypot(*d))
    if norm < 1e-6:
        return None
    across = np.array([-d[1], d[0]]) / norm * (length_m / 2.0)
    return np.stack([at - across, at + across])


def until(path: np.ndarray, at: np.ndarray) -> np.ndarray:
    """`path` [N, 2] up to its point nearest `at` [2], ending at `at`."""
    k = int(np.argmin(np.linalg.norm(path - at, axis=1)))
    before = k + 1 < len(path) and float(np.dot(at - path[k], path[k + 1] - path[k])) > 0  # `at` lies past point k
    return np.concatenate([path[: k + 1 if before else k], at[None]])


def _words(behaviour: Any) -> str:
    return str(behaviour or "target").replace("_", " ")


def _target_marks(target: Mapping[str, Any]) -> list[TargetMark]:
    tid, other = target.get("track_id"), target.get("other_id")
    who = f"@{tid}" if tid is not None else ""
    marks = []
    raw = target.get("path") or []
    if not isinstance(raw, list | tuple):
        raise InputError(f"path must be a list of [x, y], got {type(raw).__name__}", where="TargetMark")
    path = np.asarray([_point(p, f"path[{k}]") for k, p in enumerate(raw)], np.float64).reshape(-1, 2)
    goal = target.get("goal")
    goal = None if goal is None else np.asarray(_point(goal, "goal"))
    if goal is not None and target.get("stop") and len(path) >= 2:
        path = until(path, goal)  # the agent is to stand still there: the lane beyond is not where it goes
    if len(path) >= 2:
        marks.append(TargetMark(tuple(map(tuple, path)), "path"))
    conflict = target.get("conflict")
    if conflict is not None:
        order = {True: "before", False: "after"}.get(target.get("first"), "crosses")
        label = f"{who} {order} @{other}" if other is not None else f"{who} conflict"
        marks.append(TargetMark((_point(conflict, "conflict"),), "conflict", label.strip()))
    if goal is not None:
        if target.get("stop"):
            bar = stop_bar(path, goal)
            points = (tuple(goal),) if bar is None else tuple(map(tuple, bar))
            marks.append(TargetMark(points, "stop", f"{who} stop".strip()))
        elif conflict is None or float(np.hypot(*(goal - np.asarray(_point(conflict, "conflict"))))) > SAME_POINT_M:
            marks.append(TargetMark((tuple(goal),), "goal", f"{who} {_words(target.get('behaviour'))}".strip()))
    return marks


def marks_from_prompt(report_prompt: Mapping[str, Any] | None) -> tuple[TargetMark, ...]:
    """The marks of a simulation summary's `prompt` report (`{"read", "targets", "steering"}`): per target, its
    path, its goal (a stop bar across the path where the agent must stand still there, else a goal star) and the
    conflict point of a pair behaviour (which stands for the goal where they coincide). None or {} gives none.
    Raises InputError naming the target and field that is malformed."""
    if not report_prompt:
        return ()
    if not isinstance(report_prompt, Mapping):
        raise InputError(f"must be an object, got {type(report_prompt).__name__}", where="prompt report")
    targets = report_prompt.get("targets") or []
    if not isinstance(targets, list | tuple):
        raise InputError(f"targets must be a list, got {type(targets).__name__}", where="prompt report")
    out: list[TargetMark] = []
    for i, target in enumerate(targets):
        if not isinstance(target, Mapping):
            raise InputError(f"targets[{i}] must be an object, got {type(target).__name__}", where="prompt report")
        try:
            out += _target_marks(target)
        except InputError as exc:
            raise InputError(exc.detail, where=f"prompt report, targets[{i}]") from None
    return tuple(out)
