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
  - name: cut-in                 # a parameter sweep: one case per value, named cut-in.gap_m-5, ...
    scenario: scenes/synth-onramp.tfrecord.zst
    prompts: ["@52 cuts in front of @ego with a ${gap_m} m gap"]
    sweep: {gap_m: [5, 10, 15]}  # several parameters: every combination
```

Scenario and checkpoint paths are relative to the suite file's folder (or absolute); `${NAME}` is replaced by the
environment variable NAME; `${LANGTRAJ_REAL_DATA}` is the folder `load_suite` is given (`langtraj test --real-data`),
else the variable, else `../shared/data/real` under the working directory (where the README's commands run). In
prompts, `@adv` is the case's adversary and `@ego` the ego's track id (the env replaces it at reset, when the ego is
known). A case is a `langtraj.cases.Case`, read by `read_case` (every key a `Case` has; `defaults` holds those of
`DEFAULT_KEYS`). A case's `sweep` maps parameter names to lists of values, as OpenSCENARIO's parameter sets do: the
case is expanded into one case per combination, `${NAME}` replaced by the value in every text of the case (a text
that is only `${NAME}` takes the value itself, a number staying a number). A `${NAME}` that is neither a parameter
of its case's sweep nor an environment variable is an error naming the key (a mistyped `${gapp}` would otherwise run
every variant alike), as is an unknown key (with a did-you-mean: `sweeps` for `sweep`).
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from langtraj.cases import CASE_KEYS, NAME, Case, read_case
from langtraj.errors import InputError
from langtraj.settings import read_yaml, require

REAL_DATA_VARIABLE = "LANGTRAJ_REAL_DATA"
"""The environment variable naming the folder of real scenes (as in the tests)."""
DEFAULT_REAL_DATA = Path("..") / "shared" / "data" / "real"
"""`${LANGTRAJ_REAL_DATA}` when neither a folder nor the variable is given, under the working directory: the shared
real scenes beside a checkout the README's commands run in (never the installed package's location)."""
DEFAULT_KEYS = ("seeds", "criteria", "checkpoint", "max_steps")
"""The keys a suite's `defaults` may set for every case."""
SUITE_KEYS = ("name", "defaults", "cases")
"""The keys of a suite file."""
SUITE_CASE_KEYS = (*CASE_KEYS, "sweep")
"""The keys of a case in a suite file: every key of a `Case`, and its `sweep`."""


@dataclass(frozen=True)
class Suite:
    """A scenario suite: its name, the file it was read from and its cases (each named), in file order, with where
    each was read."""

    name: str
    path: Path
    cases: tuple[Case, ...]
    sources: tuple[str, ...] = ()
    """Where each case was read in the file ("cases[3]"; the cases of one sweep share it), for errors found later."""

    def source(self, index: int) -> str:
        """Where the case at `index` of `cases` was read ("cases[3]")."""
        return self.sources[index] if index < len(self.sources) else f"cases[{index}]"

    def with_seeds(self, count: int) -> Suite:
        """The suite with every case's seeds replaced by 0..count-1 (`langtraj test --seeds N`)."""
        if count < 1:
            raise InputError(f"must be >= 1, got {count}", where="--seeds")
        seeds = tuple(range(count))
        return dataclasses.replace(self, cases=tuple(dataclasses.replace(c, seeds=seeds) for c in self.cases))

    def only(self, names: Sequence[str]) -> Suite:
        """The suite with only the cases called `names` (in file order, with where each was read); an InputError
        naming those it has no case of."""
        missing = sorted(set(names) - {c.name for c in self.cases})
        if missing:
            raise InputError(f"no case {', '.join(missing)} in {self.path}", where="cases")
        kept = [k for k, c in enumerate(self.cases) if c.name in names]
        sources = tuple(self.source(k) for k in kept)
        return dataclasses.replace(self, cases=tuple(self.cases[k] for k in kept), sources=sources)

    @property
    def episodes(self) -> int:
        return sum(len(c.seeds) for c in self.cases)


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


_PARAMETER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_PLACEHOLDER = re.compile(r"\$\{([^}]*)\}")
"""`${NAME}` in a text: a sweep parameter or an environment variable (anything else between the braces is neither)."""


def check_keys(data: Any, known: Sequence[str], where: str) -> None:
    """Raise InputError at `where` when the mapping `data` has keys not in `known`, listing them (each with a
    did-you-mean where one is close) and the known keys."""
    if not isinstance(data, Mapping):
        return
    unknown = sorted((k for k in data if k not in known), key=str)
    if not unknown:
        return
    named = []
    for key in unknown:
        close = difflib.get_close_matches(str(key), known, n=1, cutoff=0.75)
        named.append(f"{key} (did you mean {close[0]}?)" if close else str(key))
    raise InputError(f"unknown keys {', '.join(named)}; known: {', '.join(known)}", where=where)


def swept(raw: Any, where: str, variables: Mapping[str, str] | None = None) -> list[Any]:
    """The cases a suite case stands for: itself, or with a `sweep` one per combination of its parameters' values,
    named `NAME.PARAM-VALUE...`; in each, `${NAME}` replaced by its sweep value, else by the environment variable
    from `variables` (default: the environment), any other `${...}` an InputError naming the key (`expanded`)."""
    variables = os.environ if variables is None else variables
    if not isinstance(raw, dict):
        return [raw]
    if "sweep" not in raw:
        return [expanded(raw, where, variables, parameters={})]
    sweep, case = raw["sweep"], {k: v for k, v in raw.items() if k != "sweep"}
    require(isinstance(sweep, dict) and bool(sweep), f"{where}.sweep", "expected a mapping of parameters to values")
    for name, values in sweep.items():
        at = f"{where}.sweep.{name}"
        require(isinstance(name, str) and bool(_PARAMETER.fullmatch(name)), at, "expected a parameter name")
        ok = isinstance(values, list) and bool(values) and all(isinstance(v, int | float | str) for v in values)
        require(ok, at, f"expected a non-empty list of numbers or texts, got {values!r}")
        require(len(set(map(str, values))) == len(values), at, "the same value twice")
    out = []
    for combination in itertools.product(*sweep.values()):
        given = dict(zip(sweep, combination, strict=True))
        one = expanded(case, where, variables, parameters=given)
        if isinstance(one.get("name"), str):
            one["name"] += "".join(f".{k}-{v}" for k, v in given.items())
        out.append(one)
    return out


def expanded(
    value: Any, where: str, variables: Mapping[str, str], *, parameters: Mapping[str, Any] | None = None
) -> Any:
    """`value` with every `${NAME}` in its texts replaced, in one pass: by `parameters[NAME]` (a case's sweep values;
    a text that is only `${NAME}` takes the value itself), else by `variables[NAME]` (the environment). Any other
    `${...}` raises InputError at the key it is in (`where.prompts[0]`): left in, it would be read as it stands.
    `parameters`: None where there is no sweep (a suite's defaults), {} for a case without one."""
    if isinstance(value, dict):
        return {k: expanded(v, f"{where}.{k}", variables, parameters=parameters) for k, v in value.items()}
    if isinstance(value, list):
        return [expanded(v, f"{where}[{j}]", variables, parameters=parameters) for j, v in enumerate(value)]
    if not isinstance(value, str):
        return value
    given = parameters or {}
    whole = _PLACEHOLDER.fullmatch(value)
    if whole and whole.group(1) in given:
        return given[whole.group(1)]

    def one(match: re.Match) -> str:
        name = match.group(1)
        if name in given:
            return str(given[name])
        if name in variables:
            return variables[name]
        raise InputError(_not_replaced(match.group(0), name, parameters), where=where)

    return _PLACEHOLDER.sub(one, value)


def _not_replaced(placeholder: str, name: str, parameters: Mapping[str, Any] | None) -> str:
    """Why `placeholder` stays: what it is not, the case's parameters, and the one it is closest to."""
    if parameters is None:
        return f"{placeholder} is not an environment variable"
    if not parameters:
        return f"{placeholder} is not a sweep parameter of this case (it has no sweep) nor an environment variable"
    names = [str(p) for p in parameters]
    message = (
        f"{placeholder} is not a sweep parameter of this case (its parameters: {', '.join(names)}) "
        "nor an environment variable"
    )
    close = difflib.get_close_matches(name, names, n=1, cutoff=0.6)
    return f"{message}; did you mean ${{{close[0]}}}?" if close else message


def _parse_suite(data: dict[str, Any], path: Path, variables: dict[str, str]) -> Suite:
    check_keys(data, SUITE_KEYS, "")
    name = data.get("name")
    ok = isinstance(name, str) and bool(NAME.fullmatch(name))
    require(ok, "name", f"expected a name of letters, digits, '.', '_' and '-', got {name!r}")
    base = path.resolve().parent
    paths = {"base": base, "variables": variables}
    raw_defaults = data.get("defaults") or {}
    check_keys(raw_defaults, DEFAULT_KEYS, "defaults")
    raw_defaults = expanded(raw_defaults, "defaults", variables)
    defaults = read_case(raw_defaults, where="defaults", keys=DEFAULT_KEYS, **paths)
    raw_cases = data.get("cases")
    require(isinstance(raw_cases, list) and bool(raw_cases), "cases", "expected a non-empty list of cases")
    cases, sources = [], []
    for i, raw in enumerate(raw_cases):
        check_keys(raw, SUITE_CASE_KEYS, f"cases[{i}]")
        for one in swept(raw, f"cases[{i}]", variables):
            cases.append(read_case(one, where=f"cases[{i}]", defaults=defaults, required=("name", "scenario"), **paths))
            sources.append(f"cases[{i}]")
    seen: dict[str, int] = {}
    for i, case in enumerate(cases):
        require(
            case.name not in seen,
            f"cases[{i}].name",
            f"{case.name!r} is already the name of cases[{seen.get(case.name)}]",
        )
        seen[case.name] = i
    return Suite(name=name, path=path, cases=tuple(cases), sources=tuple(sources))
