"""The open-loop experiment of docs/experiments.md: minADE over 6 samples on held-out synthesized
windows for constant velocity and each given checkpoint, with and without the ground-truth prompt.

    python -m langtraj.training.experiments --data LABELS_DIR --checkpoint NAME=CKPT [...] [--windows N]
"""

from __future__ import annotations

import argparse
import json
import time

from langtraj.training.evaluation import open_loop_table
from langtraj.training.run import module_from_checkpoint


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", required=True, help="InterDrive dataset folder (its val split is held out)")
    parser.add_argument("--checkpoint", action="append", required=True, help="NAME=PATH, repeatable")
    parser.add_argument("--windows", type=int, default=None, help="score at most this many held-out windows")
    parser.add_argument("--samples", type=int, default=6)
    parser.add_argument("--steps", type=int, default=10, help="DDIM steps")
    parser.add_argument("--cfg", type=float, default=0.0, help="classifier-free guidance weight with text (0: plain)")
    parser.add_argument("--json", help="also write the figures here")
    args = parser.parse_args(argv)
    results = {}
    for item in args.checkpoint:
        name, _, path = item.partition("=")
        start = time.perf_counter()
        module = module_from_checkpoint(path)
        results[name] = open_loop_table(
            module,
            args.data,
            num_samples=args.samples,
            steps=args.steps,
            max_windows=args.windows,
            guidance_weight=args.cfg,
        )
        results[name]["seconds"] = time.perf_counter() - start
    first = next(iter(results.values()))
    print(
        f"held-out windows {int(first['windows'])}, agents scored {int(first['scored_agents'])}, "
        f"prompted agents {int(first['prompted_agents'])}, minADE over {args.samples} samples (m)"
    )
    print("| model | all agents | prompted agents |\n| --- | --- | --- |")
    print(f"| constant velocity | {first['cv_all']:.3f} | {first['cv_prompted']:.3f} |")
    for name, r in results.items():
        print(f"| {name}, no text | {r['model_no_text_all']:.3f} | {r['model_no_text_prompted']:.3f} |")
        if "model_text_all" in r:
            print(f"| {name}, ground-truth prompt | {r['model_text_all']:.3f} | {r['model_text_prompted']:.3f} |")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=2)


if __name__ == "__main__":
    main()
