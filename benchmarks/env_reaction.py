"""Do the simulated agents react to the ego? The ego of a real scene brakes to a stop (4 m/s^2, straight) in the
LangTraj environment; counted: the seeds in which any agent runs into it, with every other agent driven by LangTraj
and, for comparison, with every other agent replaying its log (which cannot react). docs/testing.md, 'How the
other agents react'.

    python benchmarks/env_reaction.py [--seeds 3] [--checkpoint CKPT] [--decel 4.0]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from langtraj.env import LangTrajEnv

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
CASES = (  # (file, ego): the Waymo scenes whose ego has agents behind it in its lane
    ("sd_training.tfrecord-00000-of-01000_2a1e44d405a6833f.pkl", 1629),
    ("sd_training.tfrecord-00000-of-01000_8a346109094cd5aa.pkl", 1101),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--checkpoint", type=Path)
    parser.add_argument("--decel", type=float, default=4.0)
    args = parser.parse_args()
    brake = np.array([-args.decel, 0.0])
    print("| scene | ego | others | seeds with the ego hit | hit by |")
    print("| --- | --- | --- | --- | --- |")
    for name, ego in CASES:
        for policy in ("langtraj", "log_replay"):
            env = LangTrajEnv(REAL / name, ego=ego, policy=policy, checkpoint=args.checkpoint)
            hits = []
            for seed in range(args.seeds):
                env.reset(seed=seed)
                hit: set[int] = set()
                for _ in range(80):
                    hit |= set(env.step(brake)[4]["collided_with"])
                hits.append(sorted(hit))
            scene = name.split("_")[-1].removesuffix(".pkl")
            print(f"| {scene} | {ego} | {policy} | {sum(map(bool, hits))} of {args.seeds} | {hits} |", flush=True)


if __name__ == "__main__":
    main()
