"""`report.md`: a suite run for people: a summary line, then per case a Markdown table of its episodes (seed,
status, at-fault collision, collision with whom, offroad, min TTC, progress, seconds, reason; videos of those that
did not pass linked), one of its prompts (how each was read, and per seed whether the episode followed it, and why
not), with the simulation's warnings, and one of the numbers judged (asked beside each seed's realised value); per
seed a line of the other agents' collisions and off-road, and of an ego failure that follows one; after the cases of
a sweep, a table of its parameters against the realised numbers and the outcome (docs/testing.md, 'Scenario
suites', 'Judged by numbers' and 'Traffic faults')."""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from langtraj.fileio import atomic_path
from langtraj.interdrive.judging.base import amount
from langtraj.suites.episode import EpisodeResult
from langtraj.suites.results import SuiteResults, case_measures
from langtraj.suites.traffic import traffic_text

REPORT_FILE = "report.md"
COLUMNS = (
    "seed",
    "status",
    "at-fault collision",
    "collision",
    "offroad",
    "min TTC (s)",
    "progress",
    "seconds",
    "reason",
)


def _cell(text: object) -> str:
    """`text` safe inside a table cell: one line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _step(step: int | None, ids: list[int]) -> str:
    if step is None:
        return "no"
    return f"step {step}" + (f" ({', '.join(str(i) for i in ids)})" if ids else "")


def _number(value: float | None, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _row(result: EpisodeResult) -> list[str]:
    f = result.figures
    offroad = f"step {f['first_offroad_step']}" if f.get("first_offroad_step") else "no"
    reason = "; ".join(result.reasons)
    if result.video:
        reason = f"{reason} ([video]({result.video}))"
    elif result.video_error:
        reason = f"{reason} (no video: {result.video_error})"
    return [
        str(result.seed),
        result.status.upper().replace("_", " ") if result.status != "pass" else "pass",
        _step(f.get("first_at_fault_step"), f.get("at_fault_with", [])),
        _step(f.get("first_collision_step"), f.get("collided_with", [])),
        offroad,
        _number(f.get("min_ttc")),
        _number(f.get("final_progress")),
        f"{result.seconds:.1f}",
        reason,
    ]


def summary_line(results: SuiteResults) -> str:
    """`PASS` / `FAIL`: cases and episodes counted, e.g. `FAIL: 1 of 3 cases failed, 0 errors (5 of 6 episodes
    passed) in 12.3 s`, then the traffic faults, when any (`suites.traffic`)."""
    s = results.summary()
    verdict = "PASS" if results.passed else "FAIL"
    missed = f", {s['cases_not_happened']} whose scenario did not happen" if s["cases_not_happened"] else ""
    line = (
        f"{verdict}: {s['cases_failed']} of {s['cases']} cases failed, {s['cases_errors']} with errors{missed} "
        f"({s['passed']} of {s['episodes']} episodes passed) in {s['seconds']:.1f} s"
    )
    if not results.complete:
        line += f"; only {s['finished']} of {s['episodes']} episodes finished"
    if s["traffic_episodes"] or s["traffic_flagged"]:
        line += (
            f"; traffic faults in {s['traffic_episodes']} episodes ({s['traffic_collisions']} collisions among other "
            f"agents, {s['traffic_offroad']} off-road), {s['traffic_flagged']} ego failures following one "
            f"({s['traffic_flagged_failed']} failed)"
        )
    return line


def _collision_lines(episodes: list[EpisodeResult]) -> list[str]:
    """Every collision of the case's episodes, whether or not it failed a criterion, with its video."""
    lines = []
    for result in episodes:
        for c in result.figures.get("collisions", []):
            fault = "the ego at fault" if c["at_fault"] else "not the ego's fault"
            video = f" ([video]({result.video}))" if result.video else ""
            way = f", right of way by {c['right_of_way']}" if c.get("right_of_way") else ""
            lines.append(
                f"Collision, seed {result.seed}: step {c['step']} with {c['with']} ({c['kind']}{way}, {fault}){video}  "
            )
    return [""] + lines if lines else []


def _traffic_lines(episodes: list[EpisodeResult]) -> list[str]:
    """Per seed, the other agents' collisions and off-road, and why the ego's failure follows a traffic fault."""
    lines = []
    for result in episodes:
        if result.traffic is not None:
            lines.append(f"Traffic, seed {result.seed}: {_cell(traffic_text(result.traffic))}  ")
        if result.traffic_fault:
            status = result.status.upper().replace("_", " ")
            why = _cell(result.traffic_fault_reason)
            lines.append(f"**Traffic fault, seed {result.seed}** (status {status} kept): {why}  ")
    return [""] + lines if lines else []


def _verdict(verdict: dict[str, Any]) -> str:
    followed = verdict.get("followed")
    if followed is True:
        return "followed"
    if followed is False:
        return "NOT FOLLOWED" + (f": {verdict['why']}" if verdict.get("why") else "")
    return f"not judged: {verdict.get('why')}"


def _prompt_lines(episodes: list[EpisodeResult]) -> list[str]:
    """How each prompt was read (the first episode's reading: every seed reads the same text), the warnings, and per
    seed whether the played episode followed it (and why not)."""
    if not episodes or not episodes[0].prompts:
        return []
    lines = ["", "| prompt | read as | " + " | ".join(f"seed {r.seed}" for r in episodes) + " |"]
    lines.append("|" + " --- |" * (2 + len(episodes)))
    for k, prompt in enumerate(episodes[0].prompts):
        cells = [prompt["text"], prompt["reading"]]
        for result in episodes:
            cells.append(_verdict(result.prompts[k] if k < len(result.prompts) else {}))
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    warnings = sorted({w for r in episodes for w in r.prompt_warnings})
    return lines + ([""] if warnings else []) + [f"Warning: {_cell(w)}  " for w in warnings]


def _asked(row: dict[str, Any]) -> str:
    if row["asked"] is None:
        return "-"
    within = "" if row["tolerance"] is None else f" +-{amount(row['tolerance'], row['unit'])}"
    return amount(row["asked"], row["unit"]) + within


def _measure_lines(episodes: list[EpisodeResult]) -> list[str]:
    """The numbers judged of the case's prompts: per prompt and measure, the asked value (with its tolerance) beside
    each seed's realised one, `(missed)` where it failed."""
    rows = case_measures(episodes)
    if not rows:
        return []
    lines = ["", "| prompt | measure | asked | " + " | ".join(f"seed {r.seed}" for r in episodes) + " |"]
    lines.append("|" + " --- |" * (3 + len(episodes)))
    for row in rows:
        by_seed = {s["seed"]: s for s in row["seeds"]}
        cells = [row["prompt"], row["measure"], _asked(row)]
        for result in episodes:
            seed = by_seed.get(result.seed)
            if seed is None:
                cells.append("-")
                continue
            cells.append(amount(seed["realised"], row["unit"]) + (" (missed)" if seed["ok"] is False else ""))
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return lines


_SWEEP_PART = re.compile(r"\.([A-Za-z_][A-Za-z0-9_]*)-")
"""`.PARAM-` in a swept case's name (`suites.config.swept` names each `NAME.PARAM-VALUE...`)."""


def _suffix_values(suffix: str) -> list[tuple[str, str]] | None:
    parts = _SWEEP_PART.split(suffix)
    if len(parts) < 3 or parts[0] or any(not v for v in parts[2::2]):
        return None
    return list(zip(parts[1::2], parts[2::2], strict=True))


def sweep_values(names: Sequence[str]) -> list[dict[str, str]] | None:
    """The parameter values each case of one sweep carries in its name (`cut-in.gap_m-5` -> `{gap_m: 5}`), read
    after the longest name they share; None when the names do not parse alike."""
    if not names:
        return None
    for match in _SWEEP_PART.finditer(names[0]):
        base = names[0][: match.start()]
        if not all(n.startswith(base + ".") for n in names):
            continue
        parsed = [_suffix_values(n[len(base) :]) for n in names]
        keys = {tuple(k for k, _ in p) for p in parsed if p is not None}
        if None not in parsed and len(keys) == 1:
            return [dict(p) for p in parsed if p is not None]
    return None


def _sweep_lines(results: SuiteResults, cases: Sequence[Any], source: str) -> list[str]:
    """After the cases of one sweep: its parameters against each seed's realised numbers and the outcome, for the
    numbers whose asked value the sweep varies (else every asked one)."""
    values = sweep_values([c.name for c in cases])
    if values is None:
        return []
    episodes = [(params, r) for c, params in zip(cases, values, strict=True) for r in results.of_case(c.name)]
    asked: dict[str, set[Any]] = {}
    for _, result in episodes:
        for prompt in result.prompts:
            for m in prompt.get("measures", []):
                if m["asked"] is not None:
                    asked.setdefault(m["name"], set()).add(m["asked"])
    varied = {name for name, seen in asked.items() if len(seen) > 1} or set(asked)
    keys = list(values[0])
    lines = ["", f"### Sweep {source} ({', '.join(keys)})", ""]
    lines.append("| " + " | ".join([*keys, "seed", "measure", "asked", "done", "within tolerance", "status"]) + " |")
    lines.append("|" + " --- |" * (len(keys) + 6))
    count = 0
    for params, result in episodes:
        status = result.status.upper().replace("_", " ") if result.status != "pass" else "pass"
        for prompt in result.prompts:
            for m in prompt.get("measures", []):
                if m["name"] not in varied:
                    continue
                ok = {True: "yes", False: "no"}.get(m["ok"], "-")
                measure = f"@{prompt['agent']} {m['name']}"
                tolerance = "" if m["tolerance"] is None else f" +-{amount(m['tolerance'], m['unit'])}"
                cells = [*params.values(), str(result.seed), measure, amount(m["asked"], m["unit"]) + tolerance]
                cells += [amount(m["realised"], m["unit"]), ok, status]
                lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
                count += 1
    return lines if count else []


def render_report(results: SuiteResults) -> str:
    """The Markdown text of report.md."""
    header = results.header
    driver = f"`{header['planner']}`" if header["planner"] else f"command `{header['planner_cmd']}`"
    lines = [
        f"# Suite {results.suite.name}",
        "",
        f"**{summary_line(results)}**",
        "",
        f"Planner {driver}; suite file `{results.suite.path}`; step timeout {header['step_timeout']:g} s; "
        f"started {header['started']}.",
    ]
    if any(r.reads_log for r in results.episodes.values()):
        lines += ["", "**The planner read the ego's logged future: a log-replay baseline, not a planner under test.**"]
    statuses = results.case_statuses()
    sweeps: dict[str, list[Any]] = {}
    for index, case in enumerate(results.suite.cases):
        sweeps.setdefault(results.suite.source(index), []).append(case)
    for index, case in enumerate(results.suite.cases):
        ego = case.ego if case.ego is not None else "the env's choice"
        window = "" if case.window is None else f", window {case.window}"
        described = f"`{Path(case.scenario).name}` (index {case.index}{window}), ego {ego}"
        if case.adversary is not None:
            described += f", adversary {case.adversary} -> {case.target}"
        lines += ["", f"## {case.name}: {statuses[case.name].upper()}", "", described + "."]
        lines += [f"Prompt: “{' '.join(p.split())}”  " for p in case.prompts]
        lines += ["", "| " + " | ".join(COLUMNS) + " |", "|" + " --- |" * len(COLUMNS)]
        for result in results.of_case(case.name):
            lines.append("| " + " | ".join(_cell(c) for c in _row(result)) + " |")
        lines += _collision_lines(results.of_case(case.name))
        lines += _traffic_lines(results.of_case(case.name))
        lines += _prompt_lines(results.of_case(case.name))
        lines += _measure_lines(results.of_case(case.name))
        missing = [s for s in case.seeds if (case.name, s) not in results.episodes]
        if missing:
            lines += ["", f"Not finished: seeds {', '.join(map(str, missing))}."]
        group = sweeps[results.suite.source(index)]
        if len(group) > 1 and case is group[-1]:
            lines += _sweep_lines(results, group, results.suite.source(index))
    return "\n".join(lines) + "\n"


def write_report(results: SuiteResults, out: Path) -> Path:
    path = Path(out) / REPORT_FILE
    with atomic_path(path) as tmp:
        tmp.write_text(render_report(results))
    return path
