"""Operations per training step of a preset, counted with `torch.profiler` (docs/benchmarks.md, 'Operations per
step'): how many aten operations (nested calls counted, as `key_averages` counts them) one step issues, which
bounds a GPU step when each launches a small kernel. Counting, not timing: the figure is the same on any machine
and device up to the optimizer's implementation (`--device`; CUDA's AdamW is multi-tensor, CPU's too since this
benchmark's first version, both through `training.module.make_optimizer`).

One step is what training runs for a fixed batch: `LangTrajModule.objective` (the denoising loss, or Algorithm
1's closed-loop loss), backward, gradient clipping by norm and the AdamW step, under the preset's precision
(bf16-mixed: autocast to bfloat16). The batch is synthetic and of the preset's full size (`synthetic.py`). Two
warm-up steps run first (and compile the step where the preset or `--compile` asks for it). The last line is
`aten ops per step: X`.

    python benchmarks/train_ops.py --config configs/gpu-short.yaml [--batch B] [--device cpu|cuda] [--top 15]
        [--compile | --no-compile]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import torch
from synthetic import synthetic_batch

sys.path.insert(0, str(Path(__file__).resolve().parent))


def count_ops(profile: torch.profiler.profile, steps: int) -> tuple[int, list[tuple[str, float]]]:
    """Aten operations per step, and the operators with their calls per step, most frequent first."""
    rows = [(e.key, e.count / steps) for e in profile.key_averages() if e.key.startswith("aten::")]
    rows.sort(key=lambda r: -r[1])
    return round(sum(c for _, c in rows)), rows


def kernel_launches(profile: torch.profiler.profile, steps: int) -> int | None:
    """CUDA kernel launches per step (None on CPU)."""
    launches = [e for e in profile.key_averages() if e.key in ("cudaLaunchKernel", "cuLaunchKernel", "cudaLaunchKernelExC")]
    return round(sum(e.count for e in launches) / steps) if launches else None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", required=True, help="a training preset (YAML)")
    parser.add_argument("--batch", type=int, help="batch size (default: the preset's)")
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--steps", type=int, default=1, help="profiled steps (the count is per step)")
    parser.add_argument("--top", type=int, default=15, help="operators listed")
    compile_flag = parser.add_mutually_exclusive_group()
    compile_flag.add_argument("--compile", dest="compile", action="store_true", default=None)
    compile_flag.add_argument("--no-compile", dest="compile", action="store_false")
    args = parser.parse_args()

    from langtraj.training.config import load_config
    from langtraj.training.module import LangTrajModule

    config = load_config(args.config)
    batch_size = args.batch or config.batch_size
    module = LangTrajModule(config.to_dict()).to(args.device)
    module.train()
    batch = synthetic_batch(config, batch_size).to(args.device)
    optimizer = module.configure_optimizers()["optimizer"]
    autocast = config.precision in ("bf16-mixed", "16-mixed")
    device_type = "cuda" if args.device.startswith("cuda") else "cpu"

    def step(batch) -> None:
        with torch.autocast(device_type, dtype=torch.bfloat16, enabled=autocast):
            loss = module.objective(batch)["loss"]
        loss.backward()
        torch.nn.utils.clip_grad_norm_(module.parameters(), config.optim.grad_clip)
        optimizer.step()
        optimizer.zero_grad()

    for _ in range(2):
        step(batch)
    activities = [torch.profiler.ProfilerActivity.CPU]
    if args.device.startswith("cuda"):
        activities.append(torch.profiler.ProfilerActivity.CUDA)
    with torch.profiler.profile(activities=activities) as profile:
        for _ in range(args.steps):
            step(batch)
    total, rows = count_ops(profile, args.steps)
    print(
        f"{config.name}: batch {batch_size}, {args.device}, precision {config.precision}, "
        f"stage {config.stage} ({config.objective})"
    )
    print(f"top operators (calls per step):")
    for name, calls in rows[: args.top]:
        print(f"  {name:40s} {calls:10.0f}")
    launches = kernel_launches(profile, args.steps)
    if launches is not None:
        print(f"kernel launches per step: {launches}")
    print(f"aten ops per step: {total}")


if __name__ == "__main__":
    main()
