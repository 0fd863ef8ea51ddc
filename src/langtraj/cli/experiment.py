"""`langtraj experiment open-loop|closed-loop|realism|instruction-following|oracle-prompts ...`: the experiments of
docs/experiments.md (`langtraj.experiments`).

`open-loop`: minADE with and without the ground-truth prompt on held-out windows (optionally prompt
adherence and the ceiling of the text gain); `closed-loop`: realism, controllability and safety of each
method; `realism`: the closed-loop realism of each model or baseline driving every agent (the paper's
closed-loop ablation, selection and guidance variants); `instruction-following`: closed-loop GT-IFR and F-IFR
(ground-truth and feasible counterfactual prompts) with and without text, and the classifier-free guidance
table; `oracle-prompts`: a copy of a dataset whose sentences state each agent's displacement, to check the
text pathway apart from the labels.

The four tables take `--config FILE`, a YAML file of their settings under `configs/experiments/` (keys: the
flags' long names with '_' for '-', lists for the repeatable ones, whose string forms stay as shorthand); flags
given beside it override the file's values. Training runs of an experiment are `langtraj train` with its
committed config under `configs/experiments/`.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

S = argparse.SUPPRESS  # a flag not given leaves the setting to the config file or the settings' default


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("experiment", help="run an experiment of docs/experiments.md and print its table")
    sub = p.add_subparsers(dest="experiment", required=True, metavar="EXPERIMENT")

    o = _table(sub, "open-loop", "minADE with and without text on held-out windows, per checkpoint")
    o.add_argument("--data", type=Path, default=S, help="InterDrive dataset folder (its val split is held out)")
    o.add_argument(
        "--checkpoint", dest="checkpoints", metavar="NAME=PATH", action="append", default=S, help="repeatable"
    )
    o.add_argument("--windows", type=int, default=S, help="score at most this many held-out windows")
    o.add_argument("--samples", type=int, default=S, help="samples per agent (default 6)")
    o.add_argument("--steps", type=int, default=S, help="DDIM steps (default 10)")
    o.add_argument("--cfg", type=float, default=S, help="classifier-free guidance weight with text (default 0: plain)")
    o.add_argument(
        "--label-fraction",
        type=float,
        default=S,
        help="share of the other labelled agents given a single-agent sentence (the paper's 0.3, the default; the "
        "same for every checkpoint, so all are scored on the same agents)",
    )
    o.add_argument(
        "--decision-first",
        action="store_true",
        default=S,
        help="single-agent sentences go first to the agents that decide after the current step (synthesized scenes)",
    )
    o.add_argument("--text-gain", action="store_true", default=S, help="also measure adherence and its ceiling")
    o.add_argument("--prior-samples", type=int, default=S, help="draws without text for the ceiling (default 48)")

    c = _table(sub, "closed-loop", "realism, controllability and safety per method, per dataset")
    c.add_argument("--checkpoint", type=Path, default=S, help="trained checkpoint (shipped: the packaged one)")
    _datasets(c, "NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]] (split default val), repeatable")
    _closed_loop(c, rollouts=8)

    e = _table(sub, "realism", "closed-loop realism per method (every agent driven, no text), per dataset")
    e.add_argument(
        "--method",
        dest="methods",
        metavar="NAME=SPEC",
        action="append",
        default=S,
        help="NAME=SPEC (no '=' in NAME): constant_velocity, stationary, log_replay, or "
        "CKPT[|selector=S][|guidance=COST:W[+COST:W]], repeatable",
    )
    _datasets(e, "NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]] (split default val), repeatable")
    _closed_loop(e, rollouts=8)

    f = _table(sub, "failures", "each method's off-road and collision events by cause, beside the log's, per dataset")
    f.add_argument("--method", dest="methods", metavar="NAME=SPEC", action="append", default=S, help="as realism's")
    _datasets(f, "NAME=LABELS_DIR[:SPLIT[:ROLLOUTS]] (split default val), repeatable")
    _closed_loop(f, rollouts=8)
    f.add_argument("--no-floor", dest="floor", action="store_false", default=S, help="leave out the log's own row")

    i = _table(
        sub,
        "instruction-following",
        "closed-loop GT-IFR and F-IFR (feasible counterfactual prompts) without a prompt and with each of its "
        "levers (text, guidance, adherence-first selection)",
    )
    i.add_argument("--checkpoint", type=Path, default=S, help="trained checkpoint (shipped: the packaged one)")
    _datasets(i, "NAME=LABELS_DIR[:SPLIT] (split default val), repeatable")
    _closed_loop(i, rollouts=4)
    i.add_argument("--skip", type=int, default=S, help="pass over the first K windows of the split (default 0)")
    i.add_argument("--agents", type=int, default=S, help="prompted agents per window (default 2)")
    i.add_argument("--counterfactuals", type=int, default=S, help="feasible counterfactual prompts per agent (2)")
    i.add_argument("--cfg", type=float, default=S, help="classifier-free guidance weight with text (default 0)")
    i.add_argument(
        "--conditions",
        type=_names,
        default=S,
        help="comma-separated conditions to run (default all): 'no prompt', text, guidance, 'text + guidance', default",
    )
    i.add_argument("--on-road", type=float, default=S, help="on-road guidance weight (default: simulate's)")
    i.add_argument("--no-collision", type=float, default=S, help="no-collision weight (default: simulate's)")
    i.add_argument(
        "--free-text",
        type=Path,
        default=S,
        help="YAML/JSON of hand-written prompts per behaviour: each prompt is also run in their words (every lever)",
    )

    r = sub.add_parser("oracle-prompts", help="a dataset copy whose sentences state each agent's displacement")
    r.add_argument("labels", type=Path, help="InterDrive dataset folder")
    r.add_argument("--out", required=True, type=Path, help="folder for the rewritten dataset")
    r.add_argument("--bin", type=float, default=5.0, help="rounding of the displacement (m)")
    r.set_defaults(func=run_oracle_prompts)


def _table(sub: argparse._SubParsersAction, name: str, help: str) -> argparse.ArgumentParser:
    """The parser of one table's verb, with the options every table has."""
    p = sub.add_parser(name, help=help)
    p.add_argument("--config", type=Path, metavar="FILE", help="YAML settings (configs/experiments/)")
    p.add_argument("--json", type=Path, metavar="FILE", default=S, help="also write every figure here")
    p.set_defaults(func=run_table)
    return p


def _datasets(p: argparse.ArgumentParser, help: str) -> None:
    p.add_argument("--data", dest="datasets", metavar="NAME=LABELS", action="append", default=S, help=help)


def _closed_loop(p: argparse.ArgumentParser, rollouts: int) -> None:
    """The closed-loop tables' simulation flags."""
    p.add_argument("--windows", type=int, default=S, help="at most this many windows per dataset")
    p.add_argument("--rollouts", type=int, default=S, help=f"rollouts per window (default {rollouts})")
    p.add_argument("--candidates", type=int, default=S, help="candidates per replan (default 4)")
    p.add_argument("--steps", type=int, default=S, help="DDIM steps, at most the model's K (default 5)")
    p.add_argument("--seed", type=int, default=S, help="default 0")


def _names(text: str) -> list[str]:
    return [c.strip() for c in text.split(",") if c.strip()]


def run_table(args: argparse.Namespace) -> int:
    """Build the experiment's settings from `--config` and the flags given, then run it."""
    from dataclasses import fields

    from langtraj.experiments import EXPERIMENTS, experiment_settings

    names = {f.name for f in fields(EXPERIMENTS.get(args.experiment).settings)}
    given: dict[str, Any] = {k: v for k, v in vars(args).items() if k in names}  # the flags given, by setting
    settings = experiment_settings(args.experiment, args.config, given)
    EXPERIMENTS.create(args.experiment).run(settings)
    return 0


def run_oracle_prompts(args: argparse.Namespace) -> int:
    from langtraj.experiments.oracle_prompts import write_oracle_dataset

    count = write_oracle_dataset(args.labels, args.out, args.bin)
    print(f"{count} windows with oracle prompts -> {args.out}")
    return 0
