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
import importlib
import inspect
import pstats
import sys
import time
import types
from pathlib import Path

import torch

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
SCENE = REAL / "sd_training.tfrecord-00000-of-01000_2a1e44d405a6833f.pkl"

ROWS = {
    "network (scene encoder, denoiser, pose terms)": (
        "langtraj.model.scene_encoder:SceneEncoder.forward",
        "langtraj.model.denoiser:Denoiser.forward",
        "langtraj.model.denoiser:Denoiser.pose_cache",
    ),
    "guidance gradient (backward pass)": ("torch.autograd:grad",),
    "road distance (on-road cost)": ("langtraj.guidance.costs:OnRoadCost.per_agent",),
    "pair costs (no-collision, candidate overlaps)": (
        "langtraj.guidance.costs:NoCollisionCost.__call__",
        "langtraj.guidance.disks:candidate_overlaps",
    ),
    "candidate selection (all of it)": ("selectors",),
    "road field build": ("langtraj.guidance.road_field:RoadField.build",),
    "guidance step (all of it)": ("langtraj.guidance.step:reconstruction_guidance.guide",),
}
"""Each row's functions as `module:qualified.name` (a closure: its parent's name then its own; `selectors`:
the `select` of every registered candidate selector). Functions the code at hand lacks count nothing."""


def code_objects(target: str) -> list[types.CodeType]:
    """The code objects a `ROWS` entry names (none where the module or function does not exist)."""
    if target == "selectors":
        from langtraj.sim.selection import SELECTORS

        return [cls.select.__code__ for cls in SELECTORS.classes()]
    module_name, _, path = target.partition(":")
    try:
        found: object = importlib.import_module(module_name)
        *parents, last = path.split(".")
        for part in parents:
            found = getattr(found, part)
    except (ImportError, AttributeError):
        return []
    function = getattr(found, last, None)
    if function is not None:
        return [inspect.unwrap(getattr(function, "__func__", function)).__code__]
    code = getattr(found, "__code__", None)  # a closure defined inside `found`
    return [c for c in (code.co_consts if code else ()) if isinstance(c, types.CodeType) and c.co_name == last]


def cumulative(stats: pstats.Stats, targets: tuple[str, ...]) -> float:
    """Cumulative seconds of the functions `targets` name."""
    keys = {(c.co_filename, c.co_firstlineno, c.co_name) for t in targets for c in code_objects(t)}
    return sum(ct for key, (_, _, _, ct, _) in stats.stats.items() if key in keys)  # type: ignore[attr-defined]


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
    from langtraj.sim.config import SimRequest
    from langtraj.sim.engine import SimConfig, simulate
    from langtraj.sim.policies import LangTrajPolicy

    torch.set_num_threads(args.threads)
    scene = read_scenario(args.scene)
    model, data = load_model(shipped_checkpoint())
    options = {"on_road": 0.0, "no_collision": 0.0, "selector": "min_collision"} if args.paper else {}
    policy = LangTrajPolicy(model, data, SimRequest(guided_steps=args.guided_steps, **options))
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
    for label, targets in ROWS.items():
        seconds = cumulative(stats, targets)
        print(f"| {label} | {seconds:.2f} | {seconds / wall:.0%} |")


if __name__ == "__main__":
    main()
