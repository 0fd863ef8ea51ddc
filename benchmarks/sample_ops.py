"""Operations per denoising step of `langtraj simulate` on the 128-agent benchmark scene (docs/benchmarks.md,
'Operations per step'), counted with `torch.profiler` as `train_ops.py` counts a training step: the aten operations
(nested calls counted) inside each sampling step's network call (`diffusion.DENOISING_STEP`), and inside each
guided step's guidance (`diffusion.GUIDANCE_STEP`). A simulation with `simulate`'s defaults (on-road and
no-collision guidance, per-agent selection, local attention) runs whole, profiled; the counts are means over its
steps. Counting, not timing: the number of rollouts changes the tensors' sizes, not the count. The scene is
`simulate_speed.py`'s (the real scene 2a1e44d405a6833f cut to 64 agents, and a copy 1 km east). The last line is
`aten ops per denoising step: X`.

    python benchmarks/sample_ops.py [--agents 128] [--rollouts 8] [--checkpoint CKPT] [--compile] [--top 15]
"""

from __future__ import annotations

import argparse
import statistics
import sys

import torch
from simulate_speed import SCENE, scenes


def nested_ops(event, counts: dict[str, int]) -> int:
    """aten operations nested in a profiler event (its own children down), tallied per operator into `counts`."""
    total = 0
    for child in event.cpu_children:
        if child.name.startswith("aten::"):
            counts[child.name] = counts.get(child.name, 0) + 1
            total += 1
        total += nested_ops(child, counts)
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--agents", default="128", choices=["16", "32", "64", "128", "real"])
    parser.add_argument("--rollouts", type=int, default=8)
    parser.add_argument("--checkpoint", help="default: the shipped checkpoint")
    parser.add_argument("--compile", action="store_true", help="compile the denoiser (LangTraj.compile_steps)")
    parser.add_argument("--top", type=int, default=15)
    args = parser.parse_args()
    if not SCENE.is_file():
        sys.exit(f"benchmark scene not found: {SCENE}")

    from langtraj.model.checkpoint import load_model
    from langtraj.scenario.io import read_scenario
    from langtraj.sim.checkpoints import shipped_checkpoint
    from langtraj.sim.config import SimRequest
    from langtraj.sim.engine import SimConfig, simulate
    from langtraj.sim.policies import LangTrajPolicy

    device = "cuda" if torch.cuda.is_available() else "cpu"
    model, data = load_model(args.checkpoint or shipped_checkpoint())
    model.to(device)
    try:
        from langtraj.model.diffusion import DENOISING_STEP, GUIDANCE_STEP
    except ImportError:  # code from before the ranges (a baseline checkout): label the denoiser's calls here
        DENOISING_STEP, GUIDANCE_STEP = "denoising step", "guidance step"
        forward = model.denoiser.forward

        def labelled(*inputs, **options):
            with torch.profiler.record_function(DENOISING_STEP):
                return forward(*inputs, **options)

        model.denoiser.forward = labelled
    if args.compile:
        model.compile_steps(training=False)
    name, scene = next(scenes(read_scenario(SCENE), [args.agents]))
    policy = LangTrajPolicy(model, data, SimRequest(candidates=4, steps=5))
    if args.compile:  # the first simulation compiles; the profiled one runs the compiled denoiser
        simulate(scene, policy, SimConfig(rollouts=args.rollouts, seed=0))
    with torch.profiler.profile() as profile:
        result = simulate(scene, policy, SimConfig(rollouts=args.rollouts, seed=0))
    steps: list[int] = []
    guided: list[int] = []
    counts: dict[str, int] = {}
    for event in profile.events():
        if event.name == DENOISING_STEP:
            steps.append(nested_ops(event, counts))
        elif event.name == GUIDANCE_STEP:
            guided.append(nested_ops(event, {}))
    if not steps:
        sys.exit("no denoising step was profiled")
    print(
        f"{name} ({len(result.driven_ids)} driven), {args.rollouts} rollouts x 4 candidates, K = 5, {device}, "
        f"denoiser {'compiled' if args.compile else 'eager'}: {len(steps)} denoising steps, {len(guided)} guided"
    )
    print("top operators in a denoising step (calls per step):")
    for op, calls in sorted(counts.items(), key=lambda item: -item[1])[: args.top]:
        print(f"  {op:40s} {calls / len(steps):8.0f}")
    if guided:
        print(f"aten ops per guidance step: {statistics.mean(guided):.0f}")
    print(f"aten ops per denoising step: {statistics.mean(steps):.0f}")


if __name__ == "__main__":
    main()
