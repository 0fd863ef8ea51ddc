"""The planner protocol: what a test engineer writes to drive the ego of the LangTraj environment
(docs/testing.md, 'Planners').

A planner sees one ego-centred observation per 0.1 s step (`langtraj.env.spaces`) and answers with one action of
its `action_kind`. Built-in planners register in `PLANNERS`; a user's class is named "package.module:Class" and
need not import LangTraj at all: any class with callable `reset` and `act` methods is accepted (duck typing).
"""

from __future__ import annotations

import inspect
import sys
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any, ClassVar, cast

import numpy as np

from langtraj.env.spaces import ACTION_KINDS
from langtraj.errors import InputError, LangTrajError
from langtraj.registry import Registry, import_object

WHERE = "--planner"
"""How errors name the option a planner spec comes from."""


class PlannerError(LangTrajError):
    """A planner broke the protocol: its process exited, or it answered something that is not a valid reply."""


class PlannerTimeout(PlannerError):
    """A planner did not answer within its time limit."""


class Planner(ABC):
    """Drives the ego: `reset` at the start of each episode, then one `act` per step (docs/testing.md,
    'Planners'); `action_kind` says which action space `act` answers in (`langtraj.env.spaces.action_space`);
    `reads_log` that it is a log-replay baseline, which alone is given the ego's logged future (and flagged as such
    in the reports)."""

    name: ClassVar[str]
    action_kind: ClassVar[str] = "control"
    reads_log: ClassVar[bool] = False

    def reset(self, observation: dict[str, np.ndarray], info: dict[str, Any]) -> None:  # noqa: B027
        """Start of an episode: the first observation and the environment's reset info (`scenario_id`, `ego_id`,
        `step_seconds`, ...; `logged_ego`, [80, 4] logged future world x, y, heading, speed, NaN where unlogged, only
        for a planner that `reads_log`). Nothing by default."""

    @abstractmethod
    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        """The action for the next 0.1 s: float32 (2,) control or (`TRAJECTORY_POSES`, 3) trajectory."""

    def close(self) -> None:  # noqa: B027
        """End of the run: release what the planner holds (processes, files). Nothing by default."""


PLANNERS: Registry[Planner] = Registry("planner")

DEFAULT_STEP_TIMEOUT_S = 10.0
"""Seconds a planner may take per call (a step, a reply) unless told otherwise."""


def load_planner(spec: str) -> type[Planner]:
    """The planner class `spec` names: a registered name ("idm") or "package.module:Class", imported. An imported
    class may subclass `Planner` or merely have callable `reset` and `act`; anything else raises a one-line
    InputError naming `--planner` and the spec."""
    spec = spec.strip()
    if ":" not in spec:
        return PLANNERS.get(spec, where=WHERE)
    module_name, _, class_name = spec.partition(":")
    if not module_name or not class_name:
        raise InputError(f"{spec!r} is neither a planner name nor package.module:Class", where=WHERE)
    found = _import_planner(spec, module_name)
    if not inspect.isclass(found):
        raise InputError(f"{spec!r} is not a class", where=WHERE)
    if not issubclass(found, Planner):
        missing = [method for method in ("reset", "act") if not callable(getattr(found, method, None))]
        if missing:
            raise InputError(f"class {spec!r} has no {' or '.join(missing)} method", where=WHERE)
    try:
        planner_action_kind(found)
    except InputError as exc:
        raise InputError(f"{spec!r} has {exc.detail}", where=WHERE) from None
    return cast(type[Planner], found)


def _import_planner(spec: str, module_name: str) -> Any:
    """`import_object(spec)`, the working directory searched after sys.path (as for `python -m`, but never ahead of
    installed packages); a module found nowhere says how to point at it."""
    here = str(Path.cwd())
    if here not in sys.path:
        sys.path.append(here)
    try:
        return import_object(spec, WHERE)
    except InputError as exc:
        missing = exc.__cause__
        parts = module_name.split(".")
        own = isinstance(missing, ModuleNotFoundError) and missing.name in {
            ".".join(parts[: i + 1]) for i in range(len(parts))
        }
        if not own:
            raise
        raise InputError(
            f"no module {module_name!r} (of {spec!r}) in the working directory {here} or on sys.path; run from the "
            "folder that holds it or add that folder to PYTHONPATH",
            where=WHERE,
        ) from None


def planner_action_kind(planner: Any) -> str:
    """The planner's `action_kind` ("control" where it has none); anything but `ACTION_KINDS` raises InputError."""
    kind = getattr(planner, "action_kind", "control")
    if kind not in ACTION_KINDS:
        raise InputError(f"action_kind {kind!r}; expected one of {', '.join(ACTION_KINDS)}", where=WHERE)
    return str(kind)


def reset_takes_info(reset: Any) -> bool:
    """Whether a bound `reset` accepts the info as a second argument (`reset(observation, info)`), not only the
    observation (`reset(observation)`); unknown signatures are given both."""
    try:
        parameters = inspect.signature(reset).parameters.values()
    except (TypeError, ValueError):
        return True
    positional = [p for p in parameters if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    return len(positional) >= 2 or any(p.kind == p.VAR_POSITIONAL for p in parameters)


LOG_KEY = "logged_ego"
"""The reset info's key holding the ego's logged future: given only to planners that declare `reads_log`."""


def planner_reads_log(planner: Any) -> bool:
    """Whether the planner declares itself a log-replay baseline (`reads_log` True): only such a planner is given
    the ego's logged future."""
    return getattr(planner, "reads_log", False) is True


def reset_planner(planner: Any, observation: dict[str, np.ndarray], info: dict[str, Any]) -> None:
    """Calls `planner.reset(observation, info)`, or `planner.reset(observation)` for planners whose `reset`
    takes one argument (users may leave the info out); the info's logged future is left out unless the planner
    `reads_log` (no planner under test sees the future)."""
    if not planner_reads_log(planner):
        info = {k: v for k, v in info.items() if k != LOG_KEY}
    if reset_takes_info(planner.reset):
        planner.reset(observation, info)
    else:
        planner.reset(observation)
