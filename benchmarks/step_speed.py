"""Training steps per second of a preset on a fixed batch already on the device, eager and compiled, at several
batch sizes (docs/benchmarks.md, 'Operations per step'): what the step itself costs, with no loader in the way.
A step is `train_ops.py`'s (the objective under the preset's precision, backward, clipping, the optimizer). Each
setting warms up (`--warmup` steps: lazily built state and compilation), then times `--steps` steps; the median of
`--repeats` timings is reported, with the device's peak memory. `gpu_check.sh` runs it on a GPU.

    python benchmarks/step_speed.py --config configs/gpu-short.yaml [--batches 64 256] [--compile both|on|off]
        [--steps 30] [--warmup 3] [--repeats 3] [--device cuda|cpu]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from dataclasses import replace

import torch
from train_ops import step_parts


def timed(parts: dict, steps: int, device: str) -> float:
    """Seconds for `steps` steps."""
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    start = time.perf_counter()
    for _ in range(steps):
        for run in parts.values():
            run()
    if device.startswith("cuda"):
        torch.cuda.synchronize()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", required=True)
    parser.add_argument("--batches", type=int, nargs="+", default=[64, 256])
    parser.add_argument("--compile", choices=["both", "on", "off"], default="both")
    parser.add_argument("--steps", type=int, default=30)
    parser.add_argument("--warmup", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--json", help="also write the rows to this file")
    args = parser.parse_args()

    from langtraj.training.config import load_config

    base = load_config(args.config)
    settings = {"both": (False, True), "on": (True,), "off": (False,)}[args.compile]
    cuda = args.device.startswith("cuda")
    card = torch.cuda.get_device_name() if cuda else "cpu"
    print(f"{base.name} on {card}, torch {torch.__version__}, precision {base.precision}")
    rows = []
    for compiled in settings:
        for batch_size in args.batches:
            config = replace(base, compile=compiled)
            if cuda:
                torch.cuda.empty_cache()
                torch.cuda.reset_peak_memory_stats()
            parts = step_parts(config, batch_size, args.device)
            warm = timed(parts, args.warmup, args.device)
            seconds = statistics.median(timed(parts, args.steps, args.device) for _ in range(args.repeats))
            row = {
                "compile": compiled,
                "batch": batch_size,
                "steps_per_s": args.steps / seconds,
                "samples_per_s": args.steps * batch_size / seconds,
                "warmup_s": warm,
                "peak_gib": torch.cuda.max_memory_allocated() / 2**30 if cuda else None,
                "device": card,
            }
            rows.append(row)
            memory = f", peak {row['peak_gib']:.2f} GiB" if cuda else ""
            print(
                f"{'compiled' if compiled else 'eager':8s} batch {batch_size:4d}: {row['steps_per_s']:.2f} steps/s, "
                f"{row['samples_per_s']:.0f} samples/s (warm-up {warm:.1f} s){memory}"
            )
            del parts
    if args.json:
        with open(args.json, "w") as out:
            json.dump(rows, out, indent=2)


if __name__ == "__main__":
    main()
