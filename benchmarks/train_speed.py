"""Training throughput and peak memory of the `tiny` and `base` presets on this machine's CPU (or a GPU
when one is present), and sampling time for one 64-agent scene with K = 5 and K = 100 DDIM steps.

Batches are synthetic scenes of the preset's full size (every agent and map slot filled, random
plausible geometry), so the figures are an upper bound for real data with padding; they carry their target
actions, as batches from a feature store do. A step is what training runs: the loss, backward and the
optimizer the training module configures (`LangTrajModule.configure_optimizers`; plain AdamW where a
baseline's module has none to offer). Each preset runs in its own process so its peak resident memory is
its own. `--baseline-src DIR` also measures another checkout's code (its `src` folder) in the same run,
preset by preset, and prints the ratio.

    python benchmarks/train_speed.py [--presets tiny base] [--steps 10] [--base-batch 4] [--baseline-src DIR]
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
    optimizer = make_optimizer(model)
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


def make_optimizer(model) -> torch.optim.Optimizer:
    """The optimizer training uses for `model` (`training.module.make_optimizer`), or AdamW as configured before
    it existed (code from before, through --baseline-src)."""
    params = [p for p in model.parameters() if p.requires_grad]
    try:
        from langtraj.training.module import make_optimizer as training_optimizer
    except ImportError:
        return torch.optim.AdamW(params, lr=1e-4)
    return training_optimizer(params, lr=1e-4, weight_decay=0.01)


def run_one(preset: str, args: argparse.Namespace, src: str | None) -> dict:
    """`measure(preset)` in a fresh process, on this checkout's code or on `src`'s."""
    cmd = [sys.executable, __file__, "--one", preset, "--steps", str(args.steps), "--base-batch", str(args.base_batch)]
    env = {**os.environ, "HF_HUB_OFFLINE": "1"}
    if src:
        env["PYTHONPATH"] = os.pathsep.join([str(Path(src).resolve()), env.get("PYTHONPATH", "")])
    out = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if out.returncode:
        sys.exit(f"{preset} ({src or 'this checkout'}) failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def describe(r: dict, label: str) -> str:
    return (
        f"{r['preset']:5s} {label}({r['trainable_parameters'] / 1e6:.2f} M trainable, {r['agents']} agents, "
        f"{r['polylines']} polylines, batch {r['batch_size']}, {r['device']}): "
        f"{r['samples_per_second']:.2f} samples/s ({r['step_seconds']:.2f} s/step), "
        f"peak RSS {r['peak_rss_mb']:.0f} MB"
        + (f", peak GPU {r['peak_gpu_mb']:.0f} MB" if r["peak_gpu_mb"] else "")
        + f"; one 64-agent scene: K=5 {r['sample_64_agents_k5_seconds']:.2f} s, "
        f"K=100 {r['sample_64_agents_k100_seconds']:.2f} s"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--presets", nargs="+", default=["tiny", "base"])
    parser.add_argument("--steps", type=int, default=10, help="timed training steps (after 2 warm-up steps)")
    parser.add_argument("--base-batch", type=int, default=4, help="batch size of base on CPU (memory)")
    parser.add_argument("--baseline-src", help="also measure this checkout's src folder (code before a change)")
    parser.add_argument("--one", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        import langtraj

        print(f"code: {Path(langtraj.__file__).parent}", file=sys.stderr)
        print(json.dumps(measure(args.one, args.steps, args.base_batch)))
        return
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__},"
          f" threads {torch.get_num_threads()}, cuda {torch.cuda.is_available()}")  # fmt: skip
    for preset in args.presets:
        if args.baseline_src:
            before = run_one(preset, args, args.baseline_src)
            print(describe(before, f"[baseline {args.baseline_src}] "))
        after = run_one(preset, args, None)
        print(describe(after, ""))
        if args.baseline_src:
            ratio = after["samples_per_second"] / before["samples_per_second"]
            print(f"{preset}: {ratio:.2f}x the baseline's samples/s")


if __name__ == "__main__":
    main()
