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
from synthetic import synthetic_batch

ROOT = Path(__file__).resolve().parents[1]
SENTENCE = "the target agent turns left at the intersection"
"""Every agent's sentence in the measured batches (as in the figures recorded since 2026-11-23)."""


def measure(preset: str, steps: int, base_batch: int) -> dict:
    from langtraj.model.langtraj import LangTraj
    from langtraj.training.config import load_config

    config = load_config(ROOT / "configs" / f"{preset}-text.yaml")
    batch_size = base_batch if preset == "base" and not torch.cuda.is_available() else config.batch_size
    device = "cuda" if torch.cuda.is_available() else "cpu"

    model = LangTraj(config.model).to(device)
    batch = synthetic_batch(config, batch_size, text_fraction=1.0, sentence=SENTENCE).to(device)
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
    scene = synthetic_batch(config, 1, agents=64, text_fraction=1.0, sentence=SENTENCE).to(device)
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
        "agents": config.data.max_agents,
        "polylines": config.data.max_polylines,
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
