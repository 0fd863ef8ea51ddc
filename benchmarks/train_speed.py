"""Training throughput and peak memory of the `tiny` and `base` presets on this machine's CPU (or a GPU
when one is present), and sampling time for one 64-agent scene with K = 5 and K = 100 DDIM steps.

Batches are synthetic scenes of the preset's full size (every agent and map slot filled, random
plausible geometry), so the figures are an upper bound for real data with padding. Each preset runs
in its own process so its peak resident memory is its own.

    python benchmarks/train_speed.py [--presets tiny base] [--steps 10] [--base-batch 4]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]


def synthetic_batch(batch_size: int, agents: int, polylines: int, points: int, history: int, seed: int = 0):
    """A full batch of random scenes: agents on a 100 m square driving at 0-15 m/s, straight polylines."""
    from langtraj.model.batch import SceneBatch

    g = torch.Generator().manual_seed(seed)
    b, a, m, p = batch_size, agents, polylines, points
    pos = torch.rand(b, a, 2, generator=g) * 100 - 50
    heading = torch.rand(b, a, generator=g) * 6.28 - 3.14
    speed = torch.rand(b, a, generator=g) * 15
    t = torch.arange(-history + 1, 81, dtype=torch.float32) * 0.1
    direction = torch.stack([torch.cos(heading), torch.sin(heading)], -1)
    track = pos[:, :, None] + direction[:, :, None] * (speed[..., None, None] * t[:, None])
    hist = torch.zeros(b, a, history, 7)
    hist[..., 0:2] = track[:, :, :history]
    hist[..., 2] = torch.cos(heading)[..., None]
    hist[..., 3] = torch.sin(heading)[..., None]
    hist[..., 4:6] = (direction * speed[..., None])[:, :, None]
    hist[..., 6] = 1
    future = torch.cat([track[:, :, history:], heading[..., None, None].expand(b, a, 80, 1)], -1)
    start = torch.rand(b, m, 1, 2, generator=g) * 100 - 50
    angle = torch.rand(b, m, 1, generator=g) * 6.28
    steps = torch.arange(p, dtype=torch.float32)[None, None, :, None] * 2.0
    map_points = start + steps * torch.stack([torch.cos(angle), torch.sin(angle)], -1)
    return SceneBatch(
        agent_history=hist,
        history_valid=torch.ones(b, a, history, dtype=torch.bool),
        agent_type=torch.ones(b, a, dtype=torch.long),
        agent_size=torch.tensor([4.5, 2.0]).expand(b, a, 2).clone(),
        agent_valid=torch.ones(b, a, dtype=torch.bool),
        current_state=torch.stack([pos[..., 0], pos[..., 1], heading, speed], -1),
        future=future,
        future_valid=torch.ones(b, a, 80, dtype=torch.bool),
        map_points=map_points,
        map_valid=torch.ones(b, m, p, dtype=torch.bool),
        map_type=torch.full((b, m), 2, dtype=torch.long),
        text=[["the target agent turns left at the intersection"] * a for _ in range(b)],
        interaction_labelled=torch.ones(b, dtype=torch.bool),
        origin=torch.zeros(b, 3),
        agent_id=torch.arange(a).expand(b, a).clone(),
        scenario_id=[f"bench{i}" for i in range(b)],
    )


def measure(preset: str, steps: int, base_batch: int) -> dict:
    from langtraj.model.langtraj import LangTraj
    from langtraj.training.config import load_config

    config = load_config(ROOT / "configs" / f"{preset}-text.yaml")
    batch_size = base_batch if preset == "base" and not torch.cuda.is_available() else config.batch_size
    device = "cuda" if torch.cuda.is_available() else "cpu"
    data = config.data
    model = LangTraj(config.model).to(device)
    batch = synthetic_batch(batch_size, data.max_agents, data.max_polylines, data.points_per_polyline,
                            config.model.history_steps).to(device)  # fmt: skip
    optimizer = torch.optim.AdamW([p for p in model.parameters() if p.requires_grad], lr=1e-4)
    times = []
    for step in range(steps + 2):
        start = time.perf_counter()
        loss = model.loss(batch)["loss"]
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        if device == "cuda":
            torch.cuda.synchronize()
        if step >= 2:
            times.append(time.perf_counter() - start)
    model.eval()
    scene = synthetic_batch(1, 64, data.max_polylines, data.points_per_polyline, config.model.history_steps)
    scene = scene.to(device)
    sampling = {}
    for k in (5, 100):
        runs = []
        for _ in range(3):
            start = time.perf_counter()
            model.sample(scene, 1, steps=k, generator=torch.Generator(device=device).manual_seed(0))
            if device == "cuda":
                torch.cuda.synchronize()
            runs.append(time.perf_counter() - start)
        sampling[k] = statistics.median(runs)
    step_time = statistics.median(times)
    return {
        "preset": preset,
        "device": device,
        "batch_size": batch_size,
        "agents": data.max_agents,
        "polylines": data.max_polylines,
        "trainable_parameters": sum(p.numel() for p in model.parameters() if p.requires_grad),
        "step_seconds": step_time,
        "samples_per_second": batch_size / step_time,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "peak_gpu_mb": torch.cuda.max_memory_allocated() / 2**20 if device == "cuda" else None,
        "sample_64_agents_k5_seconds": sampling[5],
        "sample_64_agents_k100_seconds": sampling[100],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--presets", nargs="+", default=["tiny", "base"])
    parser.add_argument("--steps", type=int, default=10, help="timed training steps (after 2 warm-up steps)")
    parser.add_argument("--base-batch", type=int, default=4, help="batch size of base on CPU (memory)")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(args.one, args.steps, args.base_batch)))
        return
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__},"
          f" threads {torch.get_num_threads()}, cuda {torch.cuda.is_available()}")  # fmt: skip
    for preset in args.presets:
        cmd = [
            sys.executable,
            __file__,
            "--one",
            preset,
            "--steps",
            str(args.steps),
            "--base-batch",
            str(args.base_batch),
        ]
        out = subprocess.run(cmd, capture_output=True, text=True, check=True, env={**os.environ, "HF_HUB_OFFLINE": "1"})
        r = json.loads(out.stdout.strip().splitlines()[-1])
        print(
            f"{r['preset']:5s} ({r['trainable_parameters'] / 1e6:.2f} M trainable, {r['agents']} agents, "
            f"{r['polylines']} polylines, batch {r['batch_size']}, {r['device']}): "
            f"{r['samples_per_second']:.2f} samples/s ({r['step_seconds']:.2f} s/step), "
            f"peak RSS {r['peak_rss_mb']:.0f} MB"
            + (f", peak GPU {r['peak_gpu_mb']:.0f} MB" if r["peak_gpu_mb"] else "")
            + f"; one 64-agent scene: K=5 {r['sample_64_agents_k5_seconds']:.2f} s, "
            f"K=100 {r['sample_64_agents_k100_seconds']:.2f} s"
        )


if __name__ == "__main__":
    main()
