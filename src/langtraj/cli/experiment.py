"""`langtraj experiment open-loop|closed-loop|realism|instruction-following|oracle-prompts ...`: the experiments of
docs/experiments.md.

`open-loop`: minADE with and without the ground-truth prompt on held-out windows (optionally prompt
adherence and the ceiling of the text gain); `closed-loop`: realism, controllability and safety of each
method; `realism`: the closed-loop realism of each model or baseline driving every agent (the paper's
closed-loop ablation, selection and guidance variants); `instruction-following`: closed-loop GT-IFR and F-IFR
(ground-truth and feasible counterfactual prompts) with and without text, and the classifier-free guidance
table; `oracle-prompts`: a copy of a dataset whose
sentences state each agent's displacement, to check the text pathway apart from the labels. Training
runs of an experiment are `langtraj train` with its committed config under `configs/experiments/`.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("experiment", help="run an experiment of docs/experiments.md and print its table")
    sub = p.add_subparsers(dest="experiment", required=True, metavar="EXPERIMENT")

    o = sub.add_parser("open-loop", help="minADE with and without text on held-out windows, per checkpoint")
    o.add_argument("--data", required=True, type=Path, help="InterDrive dataset folder (its val split is held out)")
    o.add_argument("--checkpoint", action="append", required=True, help="NAME=PATH, repeatable")
    o.add_argument("--windows", type=int, default=None, help="score at most this many held-out windows")
    o.add_argument("--samples", type=int, default=6)
    o.add_argument("--steps", type=int, default=10, help="DDIM steps")
    o.add_argument("--cfg", type=float, default=0.0, help="classifier-free guidance weight with text (0: plain)")
    o.add_argument(
        "--label-fraction",
        type=float,
        default=0.3,
        help="share of the other labelled agents given a single-agent sentence (the paper's 0.3; the same for "
        "every checkpoint, so all are scored on the same agents)",
    )
    o.add_argument(
        "--decision-first",
        action="store_true",
        help="single-agent sentences go first to the agents that decide after the current step (synthesized scenes)",
    )
    o.add_argument("--text-gain", action="store_true", help="also measure adherence and the text-gain ceiling")
    o.add_argument("--prior-samples", type=int, default=48, help="draws without text for the ceiling")
    o.add_argument("--json", type=Path, help="also write the figures here")
    o.set_defaults(func=run_open_loop)

    c = sub.add_parser("closed-loop", help="realism, controllability and safety per method, per dataset")
    c.add_argument("--checkpoint", required=True, type=Path)
    c.add_argument(
        "--data", action="append", required=True, help="NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]] (val, --rollouts)"
    )
    c.add_argument("--windows", type=int, default=None, help="at most this many windows per dataset")
    c.add_argument("--rollouts", type=int, default=8)
    c.add_argument("--candidates", type=int, default=4)
    c.add_argument("--steps", type=int, default=5, help="DDIM steps")
    c.add_argument("--seed", type=int, default=0)
    c.add_argument("--json", type=Path, help="also write every figure here")
    c.set_defaults(func=run_closed_loop)

    e = sub.add_parser("realism", help="closed-loop realism per method (every agent driven, no text), per dataset")
    e.add_argument(
        "--method",
        action="append",
        required=True,
        help="NAME=SPEC (no '=' in NAME): constant_velocity, stationary, log_replay, or "
        "CKPT[|selector=S][|guidance=COST:W[+COST:W]]",
    )
    e.add_argument("--data", action="append", required=True, help="NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]] (val, 8)")
    e.add_argument("--windows", type=int, default=None, help="at most this many windows per dataset")
    e.add_argument("--candidates", type=int, default=4)
    e.add_argument("--steps", type=int, default=5, help="DDIM steps (at most the model's K)")
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--json", type=Path, help="also write every figure here")
    e.set_defaults(func=run_realism)

    i = sub.add_parser(
        "instruction-following",
        help="closed-loop GT-IFR and F-IFR (feasible counterfactual prompts) without a prompt and with each of its "
        "levers (text, guidance, adherence-first selection)",
    )
    i.add_argument("--checkpoint", required=True)
    i.add_argument("--data", action="append", required=True, help="NAME=LABELS_DIR[:SPLIT] (split default val)")
    i.add_argument("--windows", type=int, default=None, help="at most this many windows per dataset")
    i.add_argument("--skip", type=int, default=0, help="pass over the first K windows of the split (default 0)")
    i.add_argument("--agents", type=int, default=2, help="prompted agents per window")
    i.add_argument("--counterfactuals", type=int, default=2, help="feasible counterfactual prompts per agent")
    i.add_argument("--rollouts", type=int, default=4)
    i.add_argument("--candidates", type=int, default=4)
    i.add_argument("--steps", type=int, default=5, help="DDIM steps (at most the model's K)")
    i.add_argument("--seed", type=int, default=0)
    i.add_argument("--cfg", type=float, default=0.0, help="classifier-free guidance weight with text (default 0)")
    i.add_argument(
        "--conditions",
        help="comma-separated conditions to run (default all): 'no prompt', text, guidance, 'text + guidance', default",
    )
    i.add_argument("--on-road", type=float, default=None, help="on-road guidance weight (default: simulate's)")
    i.add_argument("--no-collision", type=float, default=None, help="no-collision weight (default: simulate's)")
    i.add_argument(
        "--free-text",
        help="YAML/JSON of hand-written prompts per behaviour: each prompt is also run in their words (every lever)",
    )
    i.add_argument("--json", help="also write every figure and judgement here")
    i.set_defaults(func=run_instruction_following)

    r = sub.add_parser("oracle-prompts", help="a dataset copy whose sentences state each agent's displacement")
    r.add_argument("labels", type=Path, help="InterDrive dataset folder")
    r.add_argument("--out", required=True, type=Path, help="folder for the rewritten dataset")
    r.add_argument("--bin", type=float, default=5.0, help="rounding of the displacement (m)")
    r.set_defaults(func=run_oracle_prompts)


def _positive(value: int | None, flag: str) -> None:
    from langtraj.errors import InputError

    if value is not None and value < 1:
        raise InputError(f"must be >= 1, got {value}", where=flag)


def run_open_loop(args: argparse.Namespace) -> int:
    from langtraj.training.experiments import open_loop_experiment

    for value, flag in ((args.windows, "--windows"), (args.samples, "--samples"), (args.steps, "--steps")):
        _positive(value, flag)
    open_loop_experiment(
        args.data,
        args.checkpoint,
        windows=args.windows,
        samples=args.samples,
        steps=args.steps,
        cfg=args.cfg,
        label_fraction=args.label_fraction,
        decision_first=args.decision_first,
        text_gain=args.text_gain,
        prior_samples=args.prior_samples,
        json_out=args.json,
    )
    return 0


def run_closed_loop(args: argparse.Namespace) -> int:
    from langtraj.sim.experiments import closed_loop_experiment

    for value, flag in ((args.windows, "--windows"), (args.rollouts, "--rollouts"), (args.candidates, "--candidates")):
        _positive(value, flag)
    closed_loop_experiment(
        args.checkpoint,
        args.data,
        windows=args.windows,
        rollouts=args.rollouts,
        candidates=args.candidates,
        steps=args.steps,
        seed=args.seed,
        json_out=args.json,
    )
    return 0


def run_realism(args: argparse.Namespace) -> int:
    from langtraj.sim.realism import realism_experiment

    for value, flag in ((args.windows, "--windows"), (args.candidates, "--candidates"), (args.steps, "--steps")):
        _positive(value, flag)
    realism_experiment(
        args.method,
        args.data,
        windows=args.windows,
        candidates=args.candidates,
        steps=args.steps,
        seed=args.seed,
        json_out=args.json,
    )
    return 0


def run_instruction_following(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from langtraj.interdrive.counterfactual import load_free_text_prompts
    from langtraj.sim.instruction import IFRSettings, instruction_following_experiment

    settings = IFRSettings(
        free_text=load_free_text_prompts(args.free_text) if args.free_text else (),
        windows=args.windows,
        agents=args.agents,
        counterfactuals=args.counterfactuals,
        rollouts=args.rollouts,
        candidates=args.candidates,
        steps=args.steps,
        seed=args.seed,
        cfg=args.cfg,
        skip=args.skip,
    )
    if args.conditions:
        settings = replace(settings, conditions=tuple(c.strip() for c in args.conditions.split(",") if c.strip()))
    if args.on_road is not None:
        settings = replace(settings, on_road=args.on_road)
    if args.no_collision is not None:
        settings = replace(settings, no_collision=args.no_collision)
    instruction_following_experiment(args.checkpoint, args.data, settings, args.json)
    return 0


def run_oracle_prompts(args: argparse.Namespace) -> int:
    from langtraj.training.oracle_prompts import write_oracle_dataset

    count = write_oracle_dataset(args.labels, args.out, args.bin)
    print(f"{count} windows with oracle prompts -> {args.out}")
    return 0
