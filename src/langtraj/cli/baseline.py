"""`langtraj baseline SCENARIO --policy NAME --out OUT.npz [--index I] [--rollouts R] [--seed S] [--noise-std M]`.

Rollouts from a model-free policy (constant velocity, log replay, stationary) in the `.npz` layout that
`langtraj evaluate` scores: the yardsticks a learned policy is compared with.

See README.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from langtraj.rollouts.baselines import BASELINES, generate_baseline
from langtraj.rollouts.container import WOSAC_ROLLOUTS
from langtraj.scenario.io import read_scenario


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("baseline", help="rollouts of a model-free policy (.npz for langtraj evaluate)")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario file (WOMD TFRecord, ScenarioNet .pkl)")
    p.add_argument("--policy", required=True, choices=BASELINES.names(), help="baseline policy")
    p.add_argument("--out", required=True, type=Path, help="rollouts .npz to write")
    p.add_argument("--index", type=int, default=0, help="scenario in the file (default 0)")
    p.add_argument("--rollouts", type=int, default=WOSAC_ROLLOUTS, help="joint rollouts (default 32)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--noise-std", type=float, default=None, help="log_replay: Gaussian noise on x, y (m)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    scenario = read_scenario(args.scenario, args.index)
    options = {} if args.noise_std is None else {"noise_std": args.noise_std}
    rollouts = generate_baseline(args.policy, scenario, args.rollouts, seed=args.seed, **options)
    rollouts.save(args.out)
    print(
        f"{args.out}: {rollouts.num_rollouts} rollouts of {rollouts.num_agents} agents over {rollouts.num_steps}"
        f" steps ({args.policy}, scenario {scenario.scenario_id})"
    )
    return 0
