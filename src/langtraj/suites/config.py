"""The scenario-suite file: a YAML list of test cases for a planner, read into frozen dataclasses with one-line
errors naming the file and the key (`suite.yaml: cases[2].criteria.min_ttc: must be >= 0`; docs/testing.md,
'Scenario suites').

```yaml
name: smoke                      # the suite's name (JUnit's testsuite)
defaults:                        # optional; every case starts from these
  seeds: 2                       # a count (0..N-1) or a list of seeds
  checkpoint: null               # the model driving the other agents (null: the shipped one)
  max_steps: null                # stop every episode after N steps (null: the env's full 80)
  criteria: {min_ttc: 0.5}       # overrides of the criteria defaults, key by key
cases:
  - name: womd-drive             # unique; letters, digits, '.', '_' and '-' (it names the case's videos)
    scenario: ${LANGTRAJ_REAL_DATA}/motion_data_one_scenario.tfrecord
    index: 0                     # which scene of the file
    window: null                 # which 9.1-s window of a longer scene (null: the scene as it is)
    ego: null                    # track id; null: the env's choice
    prompts: ["@adv changes lanes into @ego's lane and brakes hard"]
    adversary: 12
    target: ego                  # a track id or `ego`
    seeds: [0, 3]
    criteria: {no_collision: true}
```

Scenario and checkpoint paths are relative to the suite file's folder (or absolute); `${NAME}` is replaced by the
environment variable NAME; `${LANGTRAJ_REAL_DATA}` is the folder `load_suite` is given (`langtraj test --real-data`),
else the variable, else `../shared/data/real` under the working directory (where the README's commands run). In
prompts, `@adv` is the case's adversary and `@ego` the ego's track id (the env replaces it at reset, when the ego is
known).
"""

from __future__ import annotations

import dataclasses
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from langtraj.env import EPISODE_STEPS  # a full episode (8 s at 10 Hz); `max_steps` may cut it shorter
from langtraj.errors import InputError
from langtraj.settings import build_dataclass, read_yaml, require
from langtraj.sim.terms import pair_problem

REAL_DATA_VARIABLE = "LANGTRAJ_REAL_DATA"
"""The environment variable naming the folder of real scenes (as in the tests)."""
DEFAULT_REAL_DATA = Path("..") / "shared" / "data" / "real"
"""`${LANGTRAJ_REAL_DATA}` when neither a folder nor the variable is given, under the working directory: the shared
real scenes beside a checkout the README's commands run in (never the installed package's location)."""

NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
"""A suite's or case's name: letters, digits, '.', '_' and '-', not starting with a punctuation mark."""
_VARIABLE = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")
ADVERSARY_PLACEHOLDER = re.compile(r"@adv\b")


@dataclass(frozen=True)
class Criteria:
    """What an episode must keep to pass; each criterion is checked on the whole episode (docs/testing.md,
    'Scenario suites').

    no_at_fault_collision: fail when the ego causes a collision (the env's `at_fault`: the agent hit is in front).
    no_collision: fail on any collision of the ego, whoever is at fault.
    no_offroad: fail when the ego leaves the road at any step.
    min_ttc: fail when the time to collision with the nearest agent ahead drops below this many seconds (null: not
        checked).
    min_progress: fail when the ego's final progress, as a fraction of the logged ego's progress over the episode,
        stays below this (null: not checked).
    terminate_on_collision: end the episode at the ego's first collision (the verdict is then known).
    """

    no_at_fault_collision: bool = True
    no_collision: bool = False
    no_offroad: bool = True
    min_ttc: float | None = None
    min_progress: float | None = None
    terminate_on_collision: bool = True


@dataclass(frozen=True)
class SuiteCase:
    """One test case: a scene, the ego, what the other agents are asked to do, the seeds and the criteria.

    name: unique in the suite; it names the case's videos (`<name>-seed<k>.mp4`) and its JUnit test case.
    scenario: the scene file (WOMD TFRecord or ScenarioNet pickle), resolved to an absolute path.
    index: which scene of the file.
    window: which 9.1-s window of a longer scene (None: the scene as it is; `langtraj.env.Episode`).
    ego: the ego's track id; None: the env's choice.
    prompts: prompts for the other agents, `@adv` already replaced by the adversary's id; the env replaces `@ego`
        by the ego's id at reset (`langtraj.env.EGO_PLACEHOLDER`).
    adversary: a track id driven into `target` by collision guidance (None: none).
    target: the track id the adversary aims at, or "ego" (the env resolves it at reset).
    seeds: the episodes' seeds (one episode per seed).
    criteria: what each episode must keep to pass.
    checkpoint: the model that drives the other agents (None: the shipped one).
    max_steps: end every episode after this many steps (None: the env's full episode).
    """

    name: str
    scenario: Path
    index: int = 0
    window: int | None = None
    ego: int | None = None
    prompts: tuple[str, ...] = ()
    adversary: int | None = None
    target: int | str | None = None
    seeds: tuple[int, ...] = (0,)
    criteria: Criteria = field(default_factory=Criteria)
    checkpoint: Path | None = None
    max_steps: int | None = None


@dataclass(frozen=True)
class Suite:
    """A scenario suite: its name, the file it was read from and its cases, in file order."""

    name: str
    path: Path
    cases: tuple[SuiteCase, ...]

    def with_seeds(self, count: int) -> Suite:
        """The suite with every case's seeds replaced by 0..count-1 (`langtraj test --seeds N`)."""
        if count < 1:
            raise InputError(f"must be >= 1, got {count}", where="--seeds")
        seeds = tuple(range(count))
        return dataclasses.replace(self, cases=tuple(dataclasses.replace(c, seeds=seeds) for c in self.cases))

    @property
    def episodes(self) -> int:
        return sum(len(c.seeds) for c in self.cases)


_CASE_KEYS = tuple(f.name for f in dataclasses.fields(SuiteCase))
_DEFAULT_KEYS = ("seeds", "criteria", "checkpoint", "max_steps")


def load_suite(path: str | Path, *, real_data: str | Path | None = None) -> Suite:
    """The suite at `path`, `${LANGTRAJ_REAL_DATA}` in it being `real_data` when given (`real_data_folder`); any
    mistake raises one InputError naming the file and the key."""
    path = Path(path)
    variables = {**os.environ, REAL_DATA_VARIABLE: str(real_data_folder(real_data))}
    try:
        return _parse_suite(read_yaml(path), path, variables)
    except InputError as exc:
        raise exc.located(path=path) from None


def real_data_folder(given: str | Path | None = None) -> Path:
    """The folder of real scenes: `given`, else `$LANGTRAJ_REAL_DATA`, else `DEFAULT_REAL_DATA` under the working
    directory."""
    if given is not None:
        return Path(given).expanduser().resolve()
    if os.environ.get(REAL_DATA_VARIABLE):
        return Path(os.environ[REAL_DATA_VARIABLE]).expanduser().resolve()
    return (Path.cwd() / DEFAULT_REAL_DATA).resolve()


def _parse_suite(data: dict[str, Any], path: Path, variables: dict[str, str]) -> Suite:
    _known(data, ("name", "defaults", "cases"), "")
    name = data.get("name")
    require(isinstance(name, str) and bool(NAME.fullmatch(name)), "name", _name_rule(name))
    defaults = data.get("defaults") or {}
    require(isinstance(defaults, dict), "defaults", f"expected a mapping, got {type(defaults).__name__}")
    _known(defaults, _DEFAULT_KEYS, "defaults")
    base = path.resolve().parent
    criteria = defaults.get("criteria") or {}
    require(isinstance(criteria, dict), "defaults.criteria", f"expected a mapping, got {type(criteria).__name__}")
    _criteria(criteria, "defaults.criteria")  # checked here, so that a mistake is named where it is made
    seeds = _seeds(defaults["seeds"], "defaults.seeds") if defaults.get("seeds") is not None else (0,)
    checkpoint = _path(defaults.get("checkpoint"), base, "defaults.checkpoint", variables, optional=True)
    max_steps = _max_steps(defaults.get("max_steps"), "defaults.max_steps")
    raw_cases = data.get("cases")
    require(isinstance(raw_cases, list) and bool(raw_cases), "cases", "expected a non-empty list of cases")
    cases = []
    for i, raw in enumerate(raw_cases):
        where = f"cases[{i}]"
        require(isinstance(raw, dict), where, f"expected a mapping, got {type(raw).__name__}")
        cases.append(_case(raw, where, base, variables, criteria, seeds, checkpoint, max_steps))
    seen: dict[str, int] = {}
    for i, case in enumerate(cases):
        require(
            case.name not in seen,
            f"cases[{i}].name",
            f"{case.name!r} is already the name of cases[{seen.get(case.name)}]",
        )
        seen[case.name] = i
    return Suite(name=name, path=path, cases=tuple(cases))


def _case(
    raw: dict[str, Any],
    where: str,
    base: Path,
    variables: dict[str, str],
    default_criteria: dict[str, Any],
    default_seeds: tuple[int, ...],
    default_checkpoint: Path | None,
    default_max_steps: int | None,
) -> SuiteCase:
    _known(raw, _CASE_KEYS, where)
    name = raw.get("name")
    require(isinstance(name, str) and bool(NAME.fullmatch(name)), f"{where}.name", _name_rule(name))
    require("scenario" in raw, where, "missing scenario")
    scenario = _path(raw["scenario"], base, f"{where}.scenario", variables)
    index = _int(raw.get("index", 0), f"{where}.index", minimum=0)
    window = _int(raw["window"], f"{where}.window", minimum=0) if raw.get("window") is not None else None
    ego = _optional_id(raw.get("ego"), f"{where}.ego")
    adversary = _optional_id(raw.get("adversary"), f"{where}.adversary")
    target = raw.get("target")
    if target != "ego":
        target = _optional_id(target, f"{where}.target", also="or 'ego'")
    problem = pair_problem(adversary, target, ego=ego)  # the scene is read at run time, by the env
    if problem is not None:
        raise InputError(problem[1], where=f"{where}.{problem[0]}")
    prompts = raw.get("prompts") or []
    require(isinstance(prompts, list), f"{where}.prompts", f"expected a list of text, got {type(prompts).__name__}")
    texts = []
    for j, prompt in enumerate(prompts):
        at = f"{where}.prompts[{j}]"
        require(isinstance(prompt, str) and bool(prompt.strip()), at, f"expected non-empty text, got {prompt!r}")
        if ADVERSARY_PLACEHOLDER.search(prompt):
            require(adversary is not None, at, "'@adv' needs the case's adversary")
            prompt = ADVERSARY_PLACEHOLDER.sub(f"@{adversary}", prompt)
        texts.append(prompt)
    overrides = raw.get("criteria") or {}
    at = f"{where}.criteria"
    require(isinstance(overrides, dict), at, f"expected a mapping, got {type(overrides).__name__}")
    criteria = _criteria({**default_criteria, **overrides}, at)
    seeds = _seeds(raw["seeds"], f"{where}.seeds") if raw.get("seeds") is not None else default_seeds
    checkpoint = (
        _path(raw["checkpoint"], base, f"{where}.checkpoint", variables)
        if raw.get("checkpoint") is not None
        else default_checkpoint
    )
    max_steps = _max_steps(raw["max_steps"], f"{where}.max_steps") if "max_steps" in raw else default_max_steps
    return SuiteCase(
        name=name,
        scenario=scenario,
        index=index,
        window=window,
        ego=ego,
        prompts=tuple(texts),
        adversary=adversary,
        target=target,
        seeds=seeds,
        criteria=criteria,
        checkpoint=checkpoint,
        max_steps=max_steps,
    )


def _criteria(data: dict[str, Any], where: str) -> Criteria:
    criteria = build_dataclass(Criteria, data, where)
    for key in ("min_ttc", "min_progress"):
        value = getattr(criteria, key)
        require(value is None or value >= 0, f"{where}.{key}", f"must be >= 0, got {value}")
    return criteria


def _seeds(value: Any, where: str) -> tuple[int, ...]:
    if isinstance(value, int) and not isinstance(value, bool):
        require(value >= 1, where, f"a count of seeds must be >= 1, got {value}")
        return tuple(range(value))
    require(isinstance(value, list) and bool(value), where, f"expected a count or a list of seeds, got {value!r}")
    seeds = tuple(_int(s, f"{where}[{i}]", minimum=0) for i, s in enumerate(value))
    require(len(set(seeds)) == len(seeds), where, f"repeated seeds in {list(seeds)}")
    return seeds


def _max_steps(value: Any, where: str) -> int | None:
    if value is None:
        return None
    steps = _int(value, where, minimum=1)
    require(steps <= EPISODE_STEPS, where, f"must be at most {EPISODE_STEPS}, got {steps}")
    return steps


def _path(value: Any, base: Path, where: str, variables: dict[str, str], *, optional: bool = False) -> Path | None:
    if value is None and optional:
        return None
    require(isinstance(value, str) and bool(value), where, f"expected a path, got {value!r}")

    def variable(match: re.Match) -> str:
        name = match.group(1)
        require(name in variables, where, f"the environment variable {name} is not set")
        return variables[name]

    path = Path(_VARIABLE.sub(variable, value)).expanduser()
    path = path if path.is_absolute() else base / path
    require(path.is_file(), where, f"no such file: {path}")
    return path


def _int(value: Any, where: str, *, minimum: int) -> int:
    require(isinstance(value, int) and not isinstance(value, bool), where, f"expected a whole number, got {value!r}")
    require(value >= minimum, where, f"must be >= {minimum}, got {value}")
    return value


def _optional_id(value: Any, where: str, also: str = "") -> int | None:
    if value is None:
        return None
    ok = isinstance(value, int) and not isinstance(value, bool)
    require(ok, where, f"expected a track id{' ' + also if also else ''}, got {value!r}")
    return value


def _known(data: dict[str, Any], keys: tuple[str, ...], where: str) -> None:
    unknown = sorted(set(data) - set(keys))
    require(not unknown, where, f"unknown keys {', '.join(map(str, unknown))}; known: {', '.join(keys)}")


def _name_rule(value: Any) -> str:
    return f"expected a name of letters, digits, '.', '_' and '-', got {value!r}"
