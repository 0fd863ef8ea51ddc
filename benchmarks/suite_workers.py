"""Seconds for a scenario suite under `langtraj test` with one worker, with two sharing the cores (each pool worker
limits its math threads to cores / workers, `langtraj.executors.share_cores`), and with two each using every core
(OMP_NUM_THREADS set to the core count, which the workers respect: what the pool did before the limit). Medians
of the suite's own `seconds` over --repeats runs, and each against one worker.

The default suite is one real case of the example suite, 637f's pull-out (ego 1676, two seeds), IDM planner, no
video. The scene comes from ../shared/data/real (--real-data).

    python benchmarks/suite_workers.py [--repeats 3] [--suite FILE] [--real-data DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
SUITE = """name: workers-bench
defaults:
  seeds: 2
cases:
  - name: womd-637f-pull-out
    scenario: ${LANGTRAJ_REAL_DATA}/motion_data_one_scenario.tfrecord
    ego: 1676
    prompts: ["@1650 pulls out in front of @ego"]
"""


def run_suite(suite: Path, real: Path, out: Path, workers: int, threads: int | None) -> float:
    """The suite's seconds (results.json) for one `langtraj test` run."""
    env = dict(os.environ)
    for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        env.pop(name, None)
        if threads is not None:
            env[name] = str(threads)
    command = [sys.executable, "-m", "langtraj.cli.main", "test", str(suite), "--planner", "idm", "--out", str(out)]
    command += ["--workers", str(workers), "--no-video", "--real-data", str(real)]
    subprocess.run(command, env=env, check=False, capture_output=True)
    return float(json.loads((out / "results.json").read_text())["summary"]["seconds"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--suite", type=Path, default=None)
    parser.add_argument("--real-data", type=Path, default=REAL)
    args = parser.parse_args()
    cores = os.cpu_count() or 1
    with tempfile.TemporaryDirectory() as tmp:
        suite = args.suite or Path(tmp) / "suite.yaml"
        if args.suite is None:
            suite.write_text(SUITE)
        setups = {
            "1 worker": (1, None),
            "2 workers, cores shared": (2, None),
            f"2 workers, {cores} threads each": (2, cores),
        }
        medians = {}
        for label, (workers, threads) in setups.items():
            times = [
                run_suite(suite, args.real_data, Path(tmp) / f"out-{workers}-{threads}-{i}", workers, threads)
                for i in range(args.repeats)
            ]
            medians[label] = statistics.median(times)
            print(
                f"{label}: median {medians[label]:.1f} s over {args.repeats} ({', '.join(f'{t:.1f}' for t in times)})"
            )
    one = medians["1 worker"]
    for label, seconds in medians.items():
        print(f"  {label}: {seconds / one:.2f}x one worker")
    print(f"machine: {platform.processor() or platform.machine()}, {cores} cores, Python {platform.python_version()}")


if __name__ == "__main__":
    main()
