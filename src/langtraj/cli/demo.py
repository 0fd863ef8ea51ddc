"""`langtraj demo [--out DIR] [--checkpoint CKPT] [--scenario FILE]`: the one-command demo.

A scene (synthesized with SUMO unless --scenario is given) simulated unconditioned, with an InterDrive
prompt, and safety-critical (collision guidance plus the prompt), written side by side to DIR/demo.mp4
with DIR/summary.json. Takes a few minutes on a laptop CPU with the shipped checkpoint.

See README.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "demo", help="simulate a scene three ways (plain, prompted, safety-critical), side by side"
    )
    p.add_argument("--out", type=Path, default=Path("langtraj-demo"), help="output folder (default langtraj-demo)")
    p.add_argument("--checkpoint", type=Path, help="trained checkpoint (default: the shipped one)")
    p.add_argument("--scenario", type=Path, help="scene file to use instead of a synthesized one")
    p.add_argument("--rollouts", type=int, default=1, help="rollouts per run (default 1; rollout 0 is shown)")
    p.add_argument("--candidates", type=int, default=4, help="candidates per replan (default 4)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-video", action="store_true", help="skip the video (summary only)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from langtraj.experiments.demo import run_demo

    summary = run_demo(
        args.out,
        checkpoint=args.checkpoint,
        scene_file=args.scenario,
        rollouts=args.rollouts,
        candidates=args.candidates,
        seed=args.seed,
        video=not args.no_video,
    )
    print(
        f"scene {summary['scene']}: {summary['prompt_kind']} prompt {summary['prompt']!r} (logged: "
        f"{summary['logged_prompt']!r}); adversary @{summary['adversary']} -> target @{summary['target']}"
    )
    for name, run_summary in summary["runs"].items():
        print(
            f"  {name:16s} collision rate {run_summary['collision_rate']:.3f}  prompt followed "
            f"{summary['followed'][name]:.2f}  ({run_summary['seconds']:.1f} s)"
        )
    if not args.no_video:
        print(f"video: {args.out / 'demo.mp4'}")
    print(f"summary: {args.out / 'summary.json'} ({summary['seconds']:.0f} s in all)")
    return 0
