"""The one reader and the one writer of a `Case`: `read_case` turns a mapping (a suite's case or its defaults, the
env's keywords or reset options, a studio job) into a checked `Case`, any mistake one InputError naming the key;
`case_json` gives the mapping back (results.json, a job record, a case appended to a suite) (docs/testing.md,
'Cases')."""

from __future__ import annotations

import dataclasses
import os
import re
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

from langtraj.cases.case import ADVERSARY_PLACEHOLDER, EPISODE_STEPS, NAME, Case, Criteria
from langtraj.errors import InputError
from langtraj.scenario.model import Scenario
from langtraj.settings import build_dataclass, require

CASE_KEYS = tuple(f.name for f in dataclasses.fields(Case))
"""Every key of a case, in the order the writer writes them."""
_VARIABLE = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")


def read_case(
    data: Mapping[str, Any],
    *,
    where: str = "",
    defaults: Case | None = None,
    keys: Collection[str] = CASE_KEYS,
    required: Collection[str] = (),
    base: Path | None = None,
    variables: Mapping[str, str] | None = None,
) -> Case:
    """The case `data` states, every key it leaves out taken from `defaults` (its criteria key by key). `keys`: the
    keys allowed here; `required`: those that must be given. Paths are relative to `base` (default: the working
    directory) after `${NAME}` is replaced from `variables` (default: the environment), and must be files; a
    `Scenario` may stand for the file. `@adv` in a prompt becomes the adversary's id. A key given as null means
    None where the field may be None, and the default elsewhere. Raises one InputError at `where.key`."""

    def at(key: str) -> str:
        return f"{where}.{key}" if where else key

    require(isinstance(data, Mapping), where, f"expected a mapping, got {type(data).__name__}")
    unknown = sorted(set(data) - set(keys), key=str)
    require(not unknown, where, f"unknown keys {', '.join(map(str, unknown))}; known: {', '.join(keys)}")
    for key in required:
        require(data.get(key) is not None, where, f"missing {key}")
    case = defaults or Case()
    given = {k: v for k, v in data.items() if v is not None or k in _OPTIONAL}
    paths = {"base": base or Path.cwd(), "variables": os.environ if variables is None else variables}
    changes: dict[str, Any] = {}
    for key, value in given.items():
        changes[key] = _READERS[key](value, at(key), case, paths)
    case = dataclasses.replace(case, **changes)
    prompts = []
    for j, prompt in enumerate(case.prompts):
        if ADVERSARY_PLACEHOLDER.search(prompt):
            require(case.adversary is not None, f"{at('prompts')}[{j}]", "'@adv' needs the case's adversary")
            prompt = ADVERSARY_PLACEHOLDER.sub(f"@{case.adversary}", prompt)
        prompts.append(prompt)
    from langtraj.sim.terms import pair_problem  # the one rule for a collision pair; lazy: `cases` loads no torch

    problem = pair_problem(case.adversary, case.target, ego=case.ego)  # the scene's agents: checked by the sim
    if problem is not None:
        raise InputError(problem[1], where=at(problem[0]))
    return dataclasses.replace(case, prompts=tuple(prompts))


def case_json(case: Case, *, compact: bool = False) -> dict[str, Any]:
    """`case` as the mapping `read_case` reads (paths as absolute text). `compact`: leave out what equals `Case()`'s
    default, criteria key by key (a case appended to a suite; `name`, `scenario` and `seeds` are always kept, since
    a suite's defaults would otherwise replace them). Raises InputError for a case whose scene is in memory."""
    if isinstance(case.scenario, Scenario):
        raise InputError("a case whose scene is in memory cannot be written (give its file)", where="scenario")
    plain = Case()
    out: dict[str, Any] = {}
    for key in CASE_KEYS:
        value = getattr(case, key)
        if key == "criteria":
            value = {
                k: v for k, v in dataclasses.asdict(value).items() if not compact or v != getattr(plain.criteria, k)
            }
            if compact and not value:
                continue
        elif compact and key not in ("name", "scenario", "seeds") and value == getattr(plain, key):
            continue
        out[key] = _plain(value)
    return out


def _plain(value: Any) -> Any:
    if isinstance(value, Path):
        return str(value.resolve())
    if isinstance(value, tuple):
        return list(value)
    return value


# ---------------------------------------------------------------------------------------------- one key each
_OPTIONAL = frozenset({"window", "ego", "adversary", "target", "checkpoint", "max_steps", "name"})
"""Fields a null sets to None (the others take their default from null)."""


def _name(value: Any, where: str, case: Case, paths: dict) -> str | None:
    if value is None:
        return None
    ok = isinstance(value, str) and bool(NAME.fullmatch(value))
    require(ok, where, f"expected a name of letters, digits, '.', '_' and '-', got {value!r}")
    return value


def _scenario(value: Any, where: str, case: Case, paths: dict) -> Path | Scenario:
    if isinstance(value, Scenario):
        return value
    return _file(value, where, paths)


def _checkpoint(value: Any, where: str, case: Case, paths: dict) -> Path | None:
    return None if value is None else _file(value, where, paths)


def _file(value: Any, where: str, paths: dict) -> Path:
    require(isinstance(value, str | Path) and bool(str(value)), where, f"expected a path, got {value!r}")
    variables = paths["variables"]

    def variable(match: re.Match) -> str:
        name = match.group(1)
        require(name in variables, where, f"the environment variable {name} is not set")
        return variables[name]

    path = Path(_VARIABLE.sub(variable, str(value))).expanduser()
    path = path if path.is_absolute() else paths["base"] / path
    require(path.is_file(), where, f"no such file: {path}")
    return path


def _count(value: Any, where: str, *, minimum: int) -> int:
    require(isinstance(value, int) and not isinstance(value, bool), where, f"expected a whole number, got {value!r}")
    require(value >= minimum, where, f"must be >= {minimum}, got {value}")
    return value


def _index(value: Any, where: str, case: Case, paths: dict) -> int:
    return _count(value, where, minimum=0)


def _window(value: Any, where: str, case: Case, paths: dict) -> int | None:
    return None if value is None else _count(value, where, minimum=0)


def _track(value: Any, where: str, case: Case, paths: dict) -> int | None:
    if value is None:
        return None
    ok = isinstance(value, int) and not isinstance(value, bool)
    require(ok, where, f"expected a track id, got {value!r}")
    return value


def _target(value: Any, where: str, case: Case, paths: dict) -> int | str | None:
    if value == "ego":
        return value
    ok = value is None or (isinstance(value, int) and not isinstance(value, bool))
    require(ok, where, f"expected a track id or 'ego', got {value!r}")
    return value


def _prompts(value: Any, where: str, case: Case, paths: dict) -> tuple[str, ...]:
    texts = [value] if isinstance(value, str) else value  # one text is one prompt
    require(isinstance(texts, list | tuple), where, f"expected a list of text, got {type(value).__name__}")
    for j, prompt in enumerate(texts):
        ok = isinstance(prompt, str) and bool(prompt.strip())
        require(ok, f"{where}[{j}]", f"expected non-empty text, got {prompt!r}")
    return tuple(texts)


def _seeds(value: Any, where: str, case: Case, paths: dict) -> tuple[int, ...]:
    if isinstance(value, int) and not isinstance(value, bool):
        require(value >= 1, where, f"a count of seeds must be >= 1, got {value}")
        return tuple(range(value))
    ok = isinstance(value, list | tuple) and bool(value)
    require(ok, where, f"expected a count or a list of seeds, got {value!r}")
    seeds = tuple(_count(s, f"{where}[{i}]", minimum=0) for i, s in enumerate(value))
    require(len(set(seeds)) == len(seeds), where, f"repeated seeds in {list(seeds)}")
    return seeds


def _criteria(value: Any, where: str, case: Case, paths: dict) -> Criteria:
    if isinstance(value, Criteria):
        return value
    require(isinstance(value, Mapping), where, f"expected a mapping, got {type(value).__name__}")
    criteria = build_dataclass(Criteria, {**dataclasses.asdict(case.criteria), **value}, where)
    for key in ("min_ttc", "min_progress", "max_over_speed_limit"):
        number = getattr(criteria, key)
        require(number is None or number >= 0, f"{where}.{key}", f"must be >= 0, got {number}")
    return criteria


def _max_steps(value: Any, where: str, case: Case, paths: dict) -> int | None:
    if value is None:
        return None
    steps = _count(value, where, minimum=1)
    require(steps <= EPISODE_STEPS, where, f"must be at most {EPISODE_STEPS}, got {steps}")
    return steps


_READERS = {
    "scenario": _scenario,
    "index": _index,
    "window": _window,
    "ego": _track,
    "prompts": _prompts,
    "adversary": _track,
    "target": _target,
    "seeds": _seeds,
    "checkpoint": _checkpoint,
    "criteria": _criteria,
    "max_steps": _max_steps,
    "name": _name,
}
"""How each key is read (tests/cases: one per field of `Case`)."""
