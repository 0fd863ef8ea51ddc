"""Operations per training step of a preset, counted with `torch.profiler` (docs/benchmarks.md, 'Operations per
step'): how many aten operations one step issues (nested calls counted, as `key_averages` counts them). Each is at
least one kernel launch on a GPU, and a step of small operations is bound by launching them, not by arithmetic.
Counting, not timing: the figure does not depend on the machine's speed.

One step is what training runs on a batch: `LangTrajModule.objective` (the denoising loss, or Algorithm 1's
closed-loop loss) under the preset's precision (bf16-mixed: autocast to bfloat16), backward, gradient clipping by
norm and the optimizer training configures (`make_optimizer`: AdamW, fused unless a gradient scaler is in play).
The batch is synthetic, of the preset's full size, and carries its target actions as a feature store's batches do
(`synthetic.py`). With the preset's `compile: true` (or `--compile`) the network part is compiled
(`LangTraj.compile_steps`) during two warm-up steps. The count is printed per part: the network (forward and
backward), clipping and the optimizer. A CPU runs the last two tensor by tensor underneath (for gpu-short's 377
parameter tensors: 2,282 for clipping, 2,641 for the fused AdamW, 11,700 multi-tensor); on an H100 clipping
counted 1,147 and the multi-tensor AdamW 2,275. So compare GPU counts with GPU counts. The last line is
`aten ops per step: X`.

    python benchmarks/train_ops.py --config configs/gpu-short.yaml [--batch B] [--device cpu|cuda] [--top 15]
        [--compile | --no-compile] [--precision 32-true|bf16-mixed]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import replace

import torch
from synthetic import synthetic_batch

LAUNCHES = ("cudaLaunchKernel", "cuLaunchKernel", "cudaLaunchKernelExC", "cudaGraphLaunch")


def aten_ops(profile: torch.profiler.profile) -> dict[str, int]:
    """Calls of each aten operator in a profile, nested calls counted."""
    return {e.key: e.count for e in profile.key_averages() if e.key.startswith("aten::")}


def launches(profile: torch.profiler.profile) -> int | None:
    """CUDA kernel (and graph) launches in a profile (None on a CPU)."""
    found = [e.count for e in profile.key_averages() if e.key in LAUNCHES]
    return sum(found) if found else None


def step_parts(config, batch_size: int, device: str) -> dict[str, Callable[[], None]]:
    """One training step of `config` on a fixed synthetic batch of `batch_size` on `device`, in its three parts
    (network, clipping, optimizer; run in this order), each a function (`step_speed.py` times them too)."""
    from langtraj.training.module import LangTrajModule

    module = LangTrajModule(config.to_dict()).to(device)
    module.train()
    optimizer = module.configure_optimizers()["optimizer"]
    device_type = "cuda" if device.startswith("cuda") else "cpu"
    autocast = config.precision in ("bf16-mixed", "16-mixed")
    batch = synthetic_batch(config, batch_size).to(device)
    params = [p for p in module.parameters() if p.requires_grad]

    def network() -> None:
        with torch.autocast(device_type, dtype=torch.bfloat16, enabled=autocast):
            loss = module.objective(batch)["loss"]
        loss.backward()

    def clip() -> None:
        torch.nn.utils.clip_grad_norm_(params, config.optim.grad_clip)

    def update() -> None:
        optimizer.step()
        optimizer.zero_grad()

    return {"network (forward, backward)": network, "gradient clipping": clip, "optimizer": update}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--config", required=True, help="a training preset (YAML)")
    parser.add_argument("--batch", type=int, help="batch size (default: the preset's)")
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--precision", help="override the preset's precision (32-true, bf16-mixed)")
    parser.add_argument("--top", type=int, default=15, help="operators listed")
    compile_flag = parser.add_mutually_exclusive_group()
    compile_flag.add_argument("--compile", dest="compile", action="store_true", default=None, help="compile")
    compile_flag.add_argument("--no-compile", dest="compile", action="store_false", help="run eagerly")
    args = parser.parse_args()

    from langtraj.training.config import load_config

    config = load_config(args.config)
    if args.compile is not None:
        config = replace(config, compile=args.compile)
    if args.precision:
        config = replace(config, precision=args.precision)
    batch_size = args.batch or config.batch_size
    parts = step_parts(config, batch_size, args.device)
    device_type = "cuda" if args.device.startswith("cuda") else "cpu"
    for _ in range(2):  # warm-up: lazily built state, and compilation
        for run in parts.values():
            run()
    activities = [torch.profiler.ProfilerActivity.CPU]
    if device_type == "cuda":
        activities.append(torch.profiler.ProfilerActivity.CUDA)
    counts: dict[str, int] = {}
    totals: dict[str, int] = {}
    kernel_launches = 0
    for name, run in parts.items():
        with torch.profiler.profile(activities=activities) as profile:
            run()
            if device_type == "cuda":
                torch.cuda.synchronize()
        ops = aten_ops(profile)
        counts[name] = sum(ops.values())
        for op, calls in ops.items():
            totals[op] = totals.get(op, 0) + calls
        kernel_launches += launches(profile) or 0
    print(
        f"{config.name}: batch {batch_size}, {args.device}, precision {config.precision}, "
        f"compile {config.compile_mode if getattr(config, 'compile', False) else 'off'}, "  # older code: no option
        f"stage {config.stage} ({config.objective})"
    )
    print("top operators (calls per step):")
    for op, calls in sorted(totals.items(), key=lambda item: -item[1])[: args.top]:
        print(f"  {op:40s} {calls:8d}")
    for name, count in counts.items():
        print(f"{name}: {count} aten ops")
    if device_type == "cuda":
        print(f"kernel launches per step: {kernel_launches}")
    print(f"aten ops per step: {sum(counts.values())}")


if __name__ == "__main__":
    main()
