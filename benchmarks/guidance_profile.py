"""Where a guided closed-loop simulation spends its time: one simulation under cProfile, its seconds
attributed to the network, the guidance gradient, the road distance, the pair (disk) costs, candidate
selection and the road field's build.

The scene is a real WOMD scene from ../shared/data/real (default 2a1e44d405a6833f, 66 sim agents, every
one driven), simulated with `langtraj simulate`'s defaults (or the paper's setting with --paper).
Figures are cumulative seconds of the functions named in each row, so nested rows overlap: the road
distance and pair costs are counted both where guidance calls them and inside selection. cProfile adds
its own overhead; the shares, not the totals, are the point (benchmarks/simulate_speed.py times whole
simulations).

    python benchmarks/guidance_profile.py [--scene FILE] [--rollouts 8] [--threads 1] [--paper]
        [--guided-steps N]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from pathlib import Path

import torch

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
SCENE = REAL / "sd_training.tfrecord-00000-of-01000_2a1e44d405a6833f.pkl"

ROWS = {
    "network (scene encoder, denoiser, pose terms)": [("scene_encoder.py", "forward"), ("denoiser.py", "forward"),
                                                      ("denoiser.py", "pose_cache")],
    "guidance gradient (backward pass)": [("autograd/__init__.py", "grad")],
    "road distance (on-road cost)": [("costs.py", "per_agent")],
    "pair costs (no-collision, candidate overlaps)": [("costs.py", "__call__:NoCollisionCost"),
                                                      ("disks.py", "candidate_overlaps")],
    "candidate selection (all of it)": [("selection.py", "select")],
    "road field build": [("road_field.py", "build")],
    "guidance step (all of it)": [("step.py", "guide")],
}  # fmt: skip


def cumulative(stats: pstats.Stats, file: str, name: str) -> float:
    """Cumulative seconds of the functions called `name` in files ending in `file` (`NAME:Class` picks the
    function of that name defined on the line of the class's method in the file)."""
    name, _, owner = name.partition(":")
    total = 0.0
    for (path, line, function), (_, _, _, ct, _) in stats.stats.items():  # type: ignore[attr-defined]
        if not path.endswith(file) or function != name:
            continue
        if owner and owner not in _defining_class(path, line):
            continue
        total += ct
    return total


def _defining_class(path: str, line: int) -> str:
    """The name of the class whose body holds `line` of the file at `path` ('' when none)."""
    try:
        lines = Path(path).read_text().splitlines()[:line]
    except OSError:
        return ""
    for text in reversed(lines):
        if text.startswith("class "):
            return text[6:].split("(")[0].split(":")[0]
    return ""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", type=Path, default=SCENE)
    parser.add_argument("--rollouts", type=int, default=8)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--paper", action="store_true", help="the paper's setting (no guidance, min_collision)")
    parser.add_argument("--guided-steps", type=int, help="the defaults' guided denoising steps (default: simulate's)")
    args = parser.parse_args()
    if not args.scene.is_file():
        sys.exit(f"benchmark scene not found: {args.scene}")

    from langtraj.model.checkpoint import load_model
    from langtraj.scenario.io import read_scenario
    from langtraj.sim.checkpoints import shipped_checkpoint
    from langtraj.sim.engine import SimConfig, simulate
    from langtraj.sim.policies import LangTrajPolicy

    torch.set_num_threads(args.threads)
    scene = read_scenario(args.scene)
    model, data = load_model(shipped_checkpoint())
    options = {"on_road": 0.0, "no_collision": 0.0, "selector": "min_collision"} if args.paper else {}
    if args.guided_steps is not None:
        options["guided_steps"] = args.guided_steps
    policy = LangTrajPolicy(model, data, **options)
    profiler = cProfile.Profile()
    begin = time.perf_counter()
    profiler.enable()
    result = simulate(scene, policy, SimConfig(rollouts=args.rollouts, seed=0))
    profiler.disable()
    wall = time.perf_counter() - begin
    stats = pstats.Stats(profiler)
    print(
        f"{scene.scenario_id}: {len(result.driven_ids)} driven agents, {args.rollouts} rollouts, "
        f"{'paper setting' if args.paper else 'defaults'} ({policy.describe()['selector']}, guided steps "
        f"{getattr(policy, 'guided_steps', '-')}), {args.threads} torch thread(s): {wall:.1f} s under cProfile\n"
    )
    print("| part | seconds | share of the simulation |\n| --- | --- | --- |")
    for label, functions in ROWS.items():
        seconds = sum(cumulative(stats, file, name) for file, name in functions)
        print(f"| {label} | {seconds:.2f} | {seconds / wall:.0%} |")


if __name__ == "__main__":
    main()
