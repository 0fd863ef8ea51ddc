"""Scenarios per second for reading WOMD TFRecords: framing + CRC + proto parse, and full decode to arrays.

Builds a shard of N copies of the shared real Waymo scenario (or of a synthetic one of similar size
when ../shared is absent) in a temporary folder, times three kinds of pass over it and prints medians,
and the peak memory of one full pass (one record's worth, whatever the shard size).

    python benchmarks/read_womd.py [--copies 200] [--repeats 5]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import tempfile
import time
import tracemalloc
from dataclasses import replace
from pathlib import Path

from langtraj.scenario.io import read_scenario, read_scenarios, write_scenarios
from langtraj.scenario.io.tfrecord import iter_records
from langtraj.scenario.io.womd import decode_scenario

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real" / "motion_data_one_scenario.tfrecord"


def _source_scenario():
    if REAL.is_file():
        return read_scenario(REAL), f"real WOMD scenario {REAL.name}"
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from scenario_builders import make_scenario

    return make_scenario(num_agents=83), "synthetic 83-agent scenario (real file absent)"


def _timed(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--copies", type=int, default=200)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    scenario, what = _source_scenario()
    with tempfile.TemporaryDirectory() as tmp:
        shard = Path(tmp) / "shard.tfrecord"
        write_scenarios(shard, (replace(scenario, scenario_id=f"{i:06d}") for i in range(args.copies)))
        size_mb = shard.stat().st_size / 1e6
        framing = _timed(lambda: sum(1 for _ in iter_records(shard)), args.repeats)
        parse = _timed(lambda: [decode_scenario(p) for p in iter_records(shard)], args.repeats)
        full = _timed(lambda: sum(1 for _ in read_scenarios(shard)), args.repeats)
        tracemalloc.start()
        sum(1 for _ in read_scenarios(shard))
        peak_mb = tracemalloc.get_traced_memory()[1] / 1e6
        tracemalloc.stop()
    n = args.copies
    print(f"source: {what}; shard of {n} scenarios, {size_mb:.1f} MB")
    machine = platform.processor() or platform.machine()
    print(f"machine: {machine}, {os.cpu_count()} cores, python {platform.python_version()}")
    print(f"median of {args.repeats} passes, one process:")
    print(f"  framing + CRC32C only        : {n / framing:10.1f} scenarios/s ({size_mb / framing:7.1f} MB/s)")
    print(f"  read (framing + proto parse) : {n / parse:10.1f} scenarios/s")
    print(f"  full decode to Scenario      : {n / full:10.1f} scenarios/s")
    print(f"peak traced memory while decoding the whole shard: {peak_mb:.1f} MB (streaming, one record at a time)")


if __name__ == "__main__":
    main()
