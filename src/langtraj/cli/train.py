"""`langtraj train --config CONFIG --data LABELS_DIR --out RUN_DIR [--resume CKPT|auto] [--max-steps N]`.

One training stage from a YAML preset (`configs/`): checkpoints land in RUN_DIR/checkpoints/*.ckpt,
TensorBoard and CSV logs in RUN_DIR/logs/. LABELS_DIR is an InterDrive dataset (`langtraj interdrive
build`), whose records name the scenario files they label.

See README.md.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("train", help="train the LangTraj model (one stage of a configs/ preset)")
    p.add_argument("--config", required=True, type=Path, help="YAML preset, e.g. configs/tiny.yaml")
    p.add_argument("--data", required=True, type=Path, help="InterDrive dataset folder (labels + manifest)")
    p.add_argument("--out", required=True, type=Path, help="run folder for checkpoints and logs")
    p.add_argument("--resume", help="checkpoint to resume from, or 'auto' for RUN_DIR/checkpoints/last.ckpt")
    p.add_argument("--max-steps", type=int, help="override the preset's max_steps")
    p.add_argument("--init-from", help="override the preset's init_from (stage 2: the stage-1 checkpoint)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pytorch_lightning.utilities import rank_zero_only

    from langtraj.training.config import load_config
    from langtraj.training.run import train

    config = load_config(args.config)
    if args.init_from is not None:
        config = replace(config, init_from=args.init_from)
    last = train(config, args.data, args.out, resume=args.resume, max_steps=args.max_steps)
    if rank_zero_only.rank == 0:  # under DDP every process returns here; one line is enough
        print(f"{config.name} stage {config.stage}: last checkpoint {last}")
    return 0
