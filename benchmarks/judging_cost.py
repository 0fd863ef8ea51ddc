"""What judging costs an episode: real episodes of the example suite's safety-critical cases (a planner as ego, the
shipped checkpoint driving the others), each timed whole, with the time its prompts' judging took
(`suites.happened.judge_prompts`: the labelers and the judges by numbers) and, of that, the judges by numbers alone
(`BehaviourKind.judge`), as shares of the episode (docs/benchmarks.md, 'Judging by numbers: its cost').

    python benchmarks/judging_cost.py [--cases waymo-8a34-cut-in,...] [--planner idm] [--seed 0]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from suite_args import run

import langtraj.suites.episode as episode_module
from langtraj.interdrive.behaviours import kind
from langtraj.sim.prompts import read_prompts
from langtraj.suites import RunOptions, load_suite
from langtraj.suites.episode import run_episode
from langtraj.suites.happened import judge_prompts
from langtraj.suites.runner import episode_tasks

REPO = Path(__file__).resolve().parents[1]
CASES = "waymo-8a34-brake-hard.decel-6,waymo-8a34-cut-in,waymo-8a34-overtake-cut-in,womd-637f-pull-out"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", type=Path, default=REPO / "configs" / "suites" / "example.yaml")
    parser.add_argument("--cases", default=CASES, help="comma-separated case names of the suite")
    parser.add_argument("--planner", default="idm")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    suite = load_suite(args.suite).only(args.cases.split(","))
    suite = replace(suite, cases=tuple(replace(c, seeds=(args.seed,)) for c in suite.cases))
    spent: dict[str, float] = {}

    def timed(played, texts):
        start = time.perf_counter()
        verdicts = judge_prompts(played, texts)
        spent["judging"] = time.perf_counter() - start
        start = time.perf_counter()  # the judges by numbers alone, again (not counted in the episode)
        for reading in read_prompts(texts, strict=False):
            if reading.read and reading.agent is not None:
                kind(reading.behaviour).judge(played, reading.agent, reading.other, reading.asked())
        spent["numbers"] = time.perf_counter() - start
        return verdicts

    episode_module.judge_prompts = timed  # the episode's own call, timed
    rows = []
    with tempfile.TemporaryDirectory() as out:
        options = RunOptions(out=out, planner=args.planner, video=False)
        for task in episode_tasks(suite, options):
            spent.clear()
            start = time.perf_counter()
            result = run_episode(task)
            whole = time.perf_counter() - start - spent.get("numbers", 0.0)
            judging, numbers = spent.get("judging", 0.0), spent.get("numbers", 0.0)
            rows.append((task.case.name, result.status, whole, judging, numbers))
            print(
                f"{task.case.name}: {result.status}, episode {whole:.1f} s, judging {judging:.2f} s "
                f"({100 * judging / whole:.1f} %), by numbers {1000 * numbers:.1f} ms ({100 * numbers / whole:.2f} %)",
                flush=True,
            )
    judging_share = statistics.median(r[3] / r[2] for r in rows)
    numbers_share = statistics.median(r[4] / r[2] for r in rows)
    print(f"median share of the episode: judging {100 * judging_share:.1f} %, by numbers {100 * numbers_share:.2f} %")
    return 0


if __name__ == "__main__":
    run(main)
