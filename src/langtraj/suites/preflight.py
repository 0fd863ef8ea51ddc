"""Before any episode runs: every case of a suite checked against its scene as the env checks it at reset (the scene
and window load, the ego is one of the scene's agents, each prompt reads and names agents the simulation moves and
not the ego, the collision pair are sim agents), so that a suite with one bad case is bad input (exit status 2, one
line naming the suite file, the case and the prompt) before anything is written, not an error after the other cases
ran (docs/testing.md, 'Scenario suites').

The checks are the env's own (`env.environment.ego_row`, `sim.prompt_checks.check_prompts`, `sim.terms.pair_problem`),
without a model: what only the model can refuse (a prompt naming an agent it does not drive) is found at reset, and
`refused` words it alike. An env class other than the default may offer its own `check_case(case)` (raising
InputError at the case's key); one without is not checked here.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from langtraj.cases import EGO_PLACEHOLDER, Case
from langtraj.errors import InputError, one_line
from langtraj.registry import import_object
from langtraj.scenario.model import Scenario
from langtraj.suites.config import Suite
from langtraj.suites.episode import DEFAULT_ENV

_PROMPT_KEY = re.compile(r"prompts?\[(\d+)\]")
"""How the env's prompt check names a prompt in its message ("prompts[0]: ...")."""


def check_cases(suite: Suite, env: str = DEFAULT_ENV) -> list[str]:
    """Raise InputError (the suite file, `cases[i].key`, the case's name and prompt) for the first case of `suite`
    the environment class `env` ("module:Class") would refuse at reset; scenes are read once each. Returns the
    warnings about what the cases ask that their scenes rule out ("case cut-in, prompt '@52 cuts in front of @ego':
    @52 cannot cut in front of: ..."), each once, so they are said before the run. Anything else that goes wrong here
    is said among them and left to the episode, which reports it as LangTraj's error."""
    scenes: dict[tuple[str, int, int | None], Scenario] = {}
    check: Callable[[Case], list[str] | None] | None = lambda case: check_case(case, scenes)  # noqa: E731
    if env != DEFAULT_ENV:
        check = getattr(import_object(env, "env"), "check_case", None)
    if check is None:
        return []
    warnings: list[str] = []
    for i, case in enumerate(suite.cases):
        try:
            found = check(case) or []
        except InputError as exc:
            raise refused(suite, i, *_parts(exc)) from None
        except Exception as error:  # not bad input: the episode reports it as LangTraj's error, with its traceback
            warnings.append(f"case {case.name} not checked before the run: LangTraj raised {one_line(error)}")
            continue
        warnings += [w for w in found if w not in warnings]
    return warnings


def _parts(error: InputError) -> tuple[str, str | None]:
    """(message, key) of an error at a case's key; one naming a file keeps it in the message, at no key."""
    return (error.detail, error.where) if error.path is None else (str(error), None)


def check_case(case: Case, scenes: dict[tuple[str, int, int | None], Scenario] | None = None) -> list[str]:
    """Raise InputError at the key of `case` the default env refuses at reset (`where`: "ego", "window", "prompts[j]",
    "adversary" or "target"); `scenes` caches the scenes read, by (file, index, window). Returns the warnings about
    behaviours its scene rules out (`PromptCheck.warning`), each naming the case and the prompt."""
    from langtraj.env.environment import ego_row  # lazy: the env loads torch
    from langtraj.rollouts.agents import sim_agent_indices
    from langtraj.sim.prompt_checks import check_prompts
    from langtraj.sim.terms import pair_problem

    scenario = _scene(case, {} if scenes is None else scenes)
    ego_id = int(scenario.agents.ids[ego_row(scenario, case.ego)])
    prompts = [p.replace(EGO_PLACEHOLDER, f"@{ego_id}") for p in case.prompts]
    checks = check_prompts(scenario, prompts, ego=ego_id, targets=True)
    for j, prompt in enumerate(checks.prompts):
        if prompt.error is not None:  # the case's words name the prompt: not again as the check wrote it
            message = prompt.error.removeprefix("prompt: ").removeprefix(f"prompt {prompts[j]!r}: ")
            raise InputError(message, where=f"prompts[{j}]")
    warnings = [
        f"case {case.name}, prompt {case.prompts[j]!r}: {p.warning}" for j, p in enumerate(checks.prompts) if p.warning
    ]
    target = ego_id if case.target == "ego" else case.target
    sim_ids = {int(i) for i in scenario.agents.ids[sim_agent_indices(scenario)]}
    problem = pair_problem(case.adversary, target, sim_ids=sim_ids, ego=ego_id)
    if problem is not None:
        raise InputError(problem[1], where=problem[0])
    return warnings


def _scene(case: Case, scenes: dict[tuple[str, int, int | None], Scenario]) -> Scenario:
    """The case's scene (its window), as the env reads it; read once per (file, index, window)."""
    from langtraj.scenario.io import read_scenario
    from langtraj.scenario.windowing import nth_window

    source = case.scenario
    if source is None:
        raise InputError("no scenario given (a file or a Scenario)", where="scenario")
    key = (f"object {id(source)}" if isinstance(source, Scenario) else str(source), case.index, case.window)
    if key not in scenes:
        try:
            scenario = source if isinstance(source, Scenario) else read_scenario(Path(source), case.index)
        except InputError as exc:
            raise InputError(str(exc), where="scenario") from None
        if case.window is not None:
            try:
                scenario = nth_window(scenario, case.window)
            except InputError as exc:
                raise InputError(exc.detail, where="window") from None
        scenes[key] = scenario
    return scenes[key]


def refused(suite: Suite, index: int, message: str, where: str | None = None) -> InputError:
    """The one-line error for case `index` of `suite` refused for `message` at the case's key `where`: the suite file,
    `cases[i].key`, the case's name and, for a prompt, its text. A prompt refused by the sim ("prompt", "prompts")
    is found by the index its message starts with ("prompts[0]: ..."), else by the first agent it names."""
    case = suite.cases[index]
    if where in ("prompt", "prompts"):
        named = _PROMPT_KEY.match(message)
        if named:
            where, message = f"prompts[{named.group(1)}]", message[named.end() :].lstrip(": ")
        else:
            agent = re.search(r"@(\d+)\b", message)
            mentions = [j for j, p in enumerate(case.prompts) if agent and re.search(rf"@{agent.group(1)}\b", p)]
            where = f"prompts[{mentions[0]}]" if mentions else "prompts"
    what = f"case {case.name}"
    prompt = re.fullmatch(r"prompts\[(\d+)\]", where or "")
    if prompt and int(prompt.group(1)) < len(case.prompts):
        what += f", prompt {case.prompts[int(prompt.group(1))]!r}"
    source = suite.source(index)
    return InputError(f"{what}: {message}", path=suite.path, where=f"{source}.{where}" if where else source)
