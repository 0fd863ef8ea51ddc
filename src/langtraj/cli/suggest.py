"""`langtraj suggest SCENE|DIR... [--ego ID] [--behaviour NAME]... [--json] [--suite OUT.yaml] [--index N]
[--window W]`: what each scene can stage against its ego.

For every scene (folders are searched recursively; every scene of a file unless --index) and its ego (the scene's
self-driving car unless --ego), every (agent, behaviour toward the ego, parameters) the map and the agents' states
allow at the current step (`interdrive.suggest`), most natural first, with the prompt that stages it and where and
when (the target's reason). `--json` prints them as one JSON list; `--suite OUT.yaml` also writes a `langtraj test`
suite of one case per staging (docs/testing.md, 'From a folder of scenes to a report'), checked by loading it before
it replaces OUT. Bad input (a file, --ego, --behaviour, --index, --window) is one line and exit status 2, with no suite
written.

See README.md.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

import yaml

from langtraj.errors import InputError
from langtraj.interdrive.suggest import Staging, count_by_behaviour, ego_of, parse_behaviour
from langtraj.scenario.model import Scenario

SUITE_SEEDS = 1
"""Seeds per suggested case (`langtraj test --seeds N` runs more)."""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "suggest",
        help="what scenes can stage against their ego: prompts, reasons, a runnable suite",
        description="List every (agent, behaviour toward the ego, parameters) each scene's map and agents allow at "
        "its current step, most natural first, with the prompt that stages it.",
    )
    p.add_argument("scenes", nargs="+", metavar="SCENE|DIR", help="scenario files, or folders searched recursively")
    p.add_argument("--ego", type=int, metavar="ID", help="the ego's track id (default: each scene's self-driving car)")
    p.add_argument(
        "--behaviour",
        action="append",
        metavar="NAME",
        help="only this behaviour toward the ego (repeatable): cut_in, overtake_cut_in, brake_hard, tailgate, "
        "run_red_light, pull_out, yield, go_first, follow (default: every one)",
    )
    p.add_argument("--json", action="store_true", help="print a JSON list, one object per staging")
    p.add_argument("--suite", type=Path, metavar="OUT.yaml", help="write a `langtraj test` suite, a case per staging")
    p.add_argument("--index", type=int, metavar="N", help="only scene N of each file (default: every scene)")
    p.add_argument("--window", type=int, metavar="W", help="the W-th 9.1-s window of each scene (default: as it is)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from langtraj.interdrive.suggest import suggest_stagings
    from langtraj.roads import MapIndex
    from langtraj.scenario.io import expand_scenario_paths

    behaviours = None
    if args.behaviour:
        try:
            behaviours = [parse_behaviour(name) for name in args.behaviour]
        except InputError as exc:
            raise exc.located(where="--behaviour") from None
    for flag, value in (("--index", args.index), ("--window", args.window)):
        if value is not None and value < 0:
            raise InputError(f"must be >= 0, got {value}", where=flag)
    if args.suite is not None and args.suite.is_dir():
        raise InputError("is a folder; give the suite file to write (OUT.yaml)", path=args.suite, where="--suite")
    found: list[Staging] = []
    scenes = 0
    for path, index, scenario in _scenes(expand_scenario_paths(args.scenes), args.index, args.window):
        try:
            ego = ego_of(scenario, args.ego)
        except InputError as exc:
            raise InputError(exc.detail, path=path, where="--ego") from None
        stagings = suggest_stagings(
            scenario, ego=ego, behaviours=behaviours, map_index=MapIndex.build(scenario.road_map),
            scene=str(path), index=index, window=args.window,
        )  # fmt: skip
        scenes += 1
        found.extend(stagings)
        if not args.json:
            print(_table(path, index, args.window, scenario, ego, stagings), flush=True)
    if args.json:
        json.dump([s.to_json() for s in found], sys.stdout, indent=2)
        sys.stdout.write("\n")
    counts = ", ".join(f"{k} {v}" for k, v in count_by_behaviour(found).items() if v) or "none"
    summary = f"{_stagings(len(found))} in {scenes} scene(s) ({counts})"
    if args.suite is not None:
        if not found:
            raise InputError("no staging found in the scenes: no suite to write", path=args.suite, where="--suite")
        write_suite(args.suite, found)
        summary += f"; wrote {args.suite} ({len(found)} cases)"
    print(summary, file=sys.stderr if args.json else sys.stdout)
    return 0


def _scenes(paths: Sequence[Path], index: int | None, window: int | None) -> Iterator[tuple[Path, int, Scenario]]:
    """(file, index, scene) of each scene to search: every scene of each file, or scene `index`; cut to `window`."""
    from langtraj.scenario.io import read_scenario, read_scenarios
    from langtraj.scenario.windowing import nth_window

    for path in paths:
        chosen = [(index, read_scenario(path, index))] if index is not None else enumerate(read_scenarios(path))
        for i, scenario in chosen:
            if window is not None:
                try:
                    scenario = nth_window(scenario, window)
                except InputError as exc:
                    raise exc.located(path=path, where="--window") from None
            yield path, i, scenario


def _table(
    path: Path, index: int, window: int | None, scenario: Scenario, ego: int, stagings: Sequence[Staging]
) -> str:
    """A scene's stagings as a readable table under a line naming the scene, its ego and the counts."""
    cut = "" if window is None else f" window {window}"
    counts = ", ".join(f"{k} {v}" for k, v in count_by_behaviour(stagings).items() if v)
    head = f"{path} [{index}]{cut} {scenario.scenario_id}: ego @{ego}, {_stagings(len(stagings))}"
    if not stagings:
        return head + " (none the map allows at the current step)\n"
    rows = [("score", "dist", "agent", "behaviour", "prompt", "where / when")]
    rows += [
        (f"{s.score:.2f}", f"{s.distance_m:.0f} m", f"@{s.agent}", s.behaviour.value, s.prompt, s.reason)
        for s in stagings
    ]
    widths = [max(len(r[i]) for r in rows) for i in range(5)]
    lines = [f"{head} ({counts})"]
    for r in rows:
        cells = [r[0].rjust(widths[0]), r[1].rjust(widths[1])] + [r[i].ljust(widths[i]) for i in (2, 3, 4)]
        lines.append("  " + "  ".join(cells) + "  " + r[5])
    return "\n".join(lines) + "\n"


def write_suite(out: Path, stagings: Sequence[Staging]) -> None:
    """A `langtraj test` suite of one case per staging at `out`, written atomically and loaded (`load_suite`) before
    it replaces `out`: scene paths relative to its folder, the ego named, the staging's reason as a comment. A case
    that puts its agent in the ego's path (`BehaviourKind.in_path`) fails on any collision of the ego
    (`no_collision`): a red-light runner hit in the side is not the ego's fault by the rules of the road, yet a
    planner that drives into it has failed the test."""
    from langtraj.fileio import atomic_path
    from langtraj.interdrive.behaviours import kind
    from langtraj.suites.config import load_suite

    folder = out.resolve().parent
    name = _slug(out.name.split(".")[0]) or "suggested"
    lines = [
        "# Suggested by `langtraj suggest` (docs/testing.md, 'From a folder of scenes to a report'): one case per",
        "# staging the map allowed at the scene's current step, most natural first per scene. Run it with",
        f"#   langtraj test {out} --planner idm --out runs/{name}",
        f"name: {name}",
        "cases:",
    ]
    taken: set[str] = set()
    for s in stagings:
        case = {
            "name": _case_name(s, taken),
            "scenario": os.path.relpath(Path(s.scene).resolve(), folder),
            "index": s.index,
            "window": s.window,
            "ego": s.other,
            "prompts": [s.prompt],
            "seeds": SUITE_SEEDS,
        }
        if kind(s.behaviour.value).in_path:  # whoever the law blames, a planner that runs into it fails
            case["criteria"] = {"no_collision": True}
        lines.append(f"  # {s.reason} (score {s.score:.2f})")
        dumped = yaml.safe_dump([case], sort_keys=False, width=1000, allow_unicode=True)
        lines += ["  " + line for line in dumped.splitlines()]
    with atomic_path(out) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
        load_suite(tmp)  # a suite that does not load is never left behind


def _case_name(s: Staging, taken: set[str]) -> str:
    """A unique case name: scene, window, agent, behaviour and parameters ("8a346109094cd5aa-741-cut-in-gap-10")."""
    parts = [_slug(s.scenario_id), *([f"w{s.window}"] if s.window is not None else []), str(s.agent)]
    parts.append(s.behaviour.value.replace("_", "-"))
    parts += [f"{k}-{v:g}" for k, v in s.parameters.items()]
    base = "-".join(parts)
    name, n = base, 2
    while name in taken:
        name, n = f"{base}.{n}", n + 1
    taken.add(name)
    return name


def _stagings(n: int) -> str:
    return f"{n} staging" + ("" if n == 1 else "s")


def _slug(text: str) -> str:
    """`text` as a suite or case name: letters, digits, '.', '_' and '-', starting with a letter or digit."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "-", text).lstrip("-_.")
