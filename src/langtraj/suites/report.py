"""`report.md`: a suite run for people: a summary line, then per case a Markdown table of its episodes (seed,
status, at-fault collision, collision with whom, offroad, min TTC, progress, seconds, reason; videos of those that
did not pass linked) and one of its prompts (how each was read, and per seed whether the episode followed it), with
the simulation's warnings (docs/testing.md, 'Scenario suites')."""

from __future__ import annotations

from pathlib import Path

from langtraj.fileio import atomic_path
from langtraj.suites.episode import EpisodeResult
from langtraj.suites.results import SuiteResults

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
    passed) in 12.3 s`."""
    s = results.summary()
    verdict = "PASS" if results.passed else "FAIL"
    missed = f", {s['cases_not_happened']} whose scenario did not happen" if s["cases_not_happened"] else ""
    line = (
        f"{verdict}: {s['cases_failed']} of {s['cases']} cases failed, {s['cases_errors']} with errors{missed} "
        f"({s['passed']} of {s['episodes']} episodes passed) in {s['seconds']:.1f} s"
    )
    if not results.complete:
        line += f"; only {s['finished']} of {s['episodes']} episodes finished"
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


def _prompt_lines(episodes: list[EpisodeResult]) -> list[str]:
    """How each prompt was read (the first episode's reading: every seed reads the same text), the warnings, and per
    seed whether the played episode followed it."""
    if not episodes or not episodes[0].prompts:
        return []
    lines = ["", "| prompt | read as | " + " | ".join(f"seed {r.seed}" for r in episodes) + " |"]
    lines.append("|" + " --- |" * (2 + len(episodes)))
    for k, prompt in enumerate(episodes[0].prompts):
        cells = [prompt["text"], prompt["reading"]]
        for result in episodes:
            verdict = result.prompts[k] if k < len(result.prompts) else {}
            followed = verdict.get("followed")
            cells.append({True: "followed", False: "NOT FOLLOWED"}.get(followed, f"not judged: {verdict.get('why')}"))
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    warnings = sorted({w for r in episodes for w in r.prompt_warnings})
    return lines + ([""] if warnings else []) + [f"Warning: {_cell(w)}  " for w in warnings]


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
    for case in results.suite.cases:
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
        lines += _prompt_lines(results.of_case(case.name))
        missing = [s for s in case.seeds if (case.name, s) not in results.episodes]
        if missing:
            lines += ["", f"Not finished: seeds {', '.join(map(str, missing))}."]
    return "\n".join(lines) + "\n"


def write_report(results: SuiteResults, out: Path) -> Path:
    path = Path(out) / REPORT_FILE
    with atomic_path(path) as tmp:
        tmp.write_text(render_report(results))
    return path
