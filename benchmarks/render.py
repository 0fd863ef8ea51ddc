"""Milliseconds per top-down frame on the shared real Waymo scene (83 agents, 301 map features).

Times `TopDownRenderer.frame` over all 91 steps for a fixed camera, a camera following the SDC, and
with track-id labels; prints the median per-frame time of each, and the time to write a whole MP4.

    python benchmarks/render.py [--size 800]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

from langtraj.scenario.io import read_scenario
from langtraj.viz import RenderConfig, TopDownRenderer, save_video

REAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real" / "motion_data_one_scenario.tfrecord"


def _per_frame_ms(scenario, config: RenderConfig) -> float:
    times = []
    with TopDownRenderer(scenario, config) as renderer:
        for step in range(scenario.num_steps):
            start = time.perf_counter()
            renderer.frame(step)
            times.append(time.perf_counter() - start)
    return 1000 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=800)
    args = parser.parse_args()
    if not REAL.is_file():
        raise SystemExit(f"needs the shared real scenario at {REAL}")
    scenario = read_scenario(REAL)
    base = RenderConfig(size_px=args.size)
    modes = {
        "fixed camera": base,
        "follow the SDC": RenderConfig(size_px=args.size, follow_track_id=scenario.sdc_id),
        "fixed, track-id labels": RenderConfig(size_px=args.size, show_ids=True),
    }
    print(f"scene {scenario.scenario_id}: {scenario.num_agents} agents, {scenario.num_steps} steps, {args.size} px")
    print(f"machine: {os.cpu_count()} cores")
    for name, config in modes.items():
        print(f"  {name:24s}: {_per_frame_ms(scenario, config):6.1f} ms/frame (median)")
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        save_video(scenario, Path(tmp) / "scene.mp4", base, progress=False)
        print(f"  whole MP4, fixed camera : {time.perf_counter() - start:6.2f} s for {scenario.num_steps} frames")


if __name__ == "__main__":
    main()
