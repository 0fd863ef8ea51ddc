"""What staging costs an episode: real episodes of the example suite's safety-critical cases (a planner as ego, the
shipped checkpoint driving the others), each timed whole, with the time spent staging its behaviours on the ego's
live state (`sim.staging.Stagings.update`: the triggers checked at every step, each rollout's scene read, the
target derived where a trigger holds and its readiness asked), planning the scripted manoeuvres at each replan
(`CandidatePlanning._scripted`) and driving them at every step (`sim.scripted.act`), as a share of the episode
(docs/benchmarks.md, 'Staging on the live state: its cost'; the issue's target: at most 10 %).

    python benchmarks/staging_cost.py [--suite SUITE] [--cases waymo-8a34-cut-in-by-name,...] [--planner idm]
        [--seed 0]

The timed prompts run on the example suite's scene 8a34 where the suite has that case.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from suite_args import run

from langtraj.cases import Case
from langtraj.sim import scripted as scripted_module
from langtraj.sim.candidates import CandidatePlanning
from langtraj.sim.staging import Stagings
from langtraj.suites import RunOptions, load_suite
from langtraj.suites.episode import run_episode
from langtraj.suites.runner import episode_tasks

REPO = Path(__file__).resolve().parents[1]
CASES = (
    "waymo-8a34-brake-hard.decel-6,waymo-8a34-overtake-cut-in,womd-637f-pull-out,synth-onramp-cut-in-by-name.gap_m-10"
)
TIMED = (
    "@742 cuts in front of @ego with a 10 m gap after 3 s",
    "When @ego is within 15 m of @738, @738 brakes hard in front of @ego",
)
"""Prompts with timing words on the example suite's real scene 8a34 (ego 1101), timed as well."""
TIMED_ON = "waymo-8a34-brake-hard.decel-6"
"""The case whose scene and ego the timed prompts take."""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", type=Path, default=REPO / "configs" / "suites" / "example.yaml")
    parser.add_argument("--cases", default=CASES, help="comma-separated case names of the suite")
    parser.add_argument("--planner", default="idm")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    full = load_suite(args.suite)
    suite = full.only(args.cases.split(","))
    cases = [replace(c, seeds=(args.seed,)) for c in suite.cases]
    for scene in (c for c in full.cases if c.name == TIMED_ON):  # the example suite's: another suite has none
        numbered = enumerate(TIMED)
        cases += [replace(scene, name=f"timed-{k}", prompts=(text,), seeds=(args.seed,)) for k, text in numbered]
    suite = replace(suite, cases=tuple(cases))
    spent = {"staging": 0.0, "inside": 0.0}
    update = Stagings.update

    def timed(self: Stagings, scenario_at, step: int, rollouts: list[int]) -> None:
        start = time.perf_counter()
        update(self, scenario_at, step, rollouts)
        if not spent["inside"]:  # at a replan; inside `act` its time is counted there
            spent["staging"] += time.perf_counter() - start

    act = scripted_module.act

    def timed_act(*args, **kwargs):
        start, spent["inside"] = time.perf_counter(), 1.0
        try:
            return act(*args, **kwargs)
        finally:
            spent["inside"] = 0.0
            spent["staging"] += time.perf_counter() - start

    scripted = CandidatePlanning._scripted

    def timed_scripts(self, *args, **kwargs):
        start = time.perf_counter()
        out = scripted(self, *args, **kwargs)
        spent["staging"] += time.perf_counter() - start
        return out

    Stagings.update = timed  # type: ignore[method-assign]
    scripted_module.act = timed_act
    CandidatePlanning._scripted = timed_scripts  # type: ignore[method-assign]
    rows = []
    with tempfile.TemporaryDirectory() as out:
        options = RunOptions(out=out, planner=args.planner, video=False)
        for task in episode_tasks(suite, options):
            spent["staging"] = 0.0
            start = time.perf_counter()
            result = run_episode(task)
            whole = time.perf_counter() - start
            rows.append((task.case.name, whole, spent["staging"]))
            print(
                f"{_label(task.case)}: {result.status}, episode {whole:.1f} s, "
                f"staging {1000 * spent['staging']:.0f} ms ({100 * spent['staging'] / whole:.2f} %)",
                flush=True,
            )
    shares = [r[2] / r[1] for r in rows]
    median, most = 100 * statistics.median(shares), 100 * max(shares)
    print(f"share of the episode spent staging: median {median:.2f} %, most {most:.2f} %")
    return 0


def _label(case: Case) -> str:
    return f"{case.name} ({case.prompts[0]!r})" if case.prompts else case.name


if __name__ == "__main__":
    run(main)
