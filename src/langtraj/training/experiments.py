"""The open-loop experiment of docs/experiments.md: minADE over 6 samples on held-out synthesized
windows for constant velocity and each given checkpoint, with and without the ground-truth prompt.
`--text-gain` adds prompt adherence and the ceiling of the text gain (`langtraj.training.text_gain`).

    python -m langtraj.training.experiments --data LABELS_DIR --checkpoint NAME=CKPT [...] [--windows N]
        [--label-fraction 0.3] [--text-gain [--prior-samples 48]]
"""

from __future__ import annotations

import argparse
import json
import time

from langtraj.training.evaluation import open_loop_table
from langtraj.training.run import module_from_checkpoint
from langtraj.training.text_gain import TextGainConfig, text_gain_table


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--data", required=True, help="InterDrive dataset folder (its val split is held out)")
    parser.add_argument("--checkpoint", action="append", required=True, help="NAME=PATH, repeatable")
    parser.add_argument("--windows", type=int, default=None, help="score at most this many held-out windows")
    parser.add_argument("--samples", type=int, default=6)
    parser.add_argument("--steps", type=int, default=10, help="DDIM steps")
    parser.add_argument("--cfg", type=float, default=0.0, help="classifier-free guidance weight with text (0: plain)")
    parser.add_argument(
        "--label-fraction",
        type=float,
        default=0.3,
        help="share of the other labelled agents given a single-agent sentence (the paper's 0.3; the same for "
        "every checkpoint, so all are scored on the same agents)",
    )
    parser.add_argument("--text-gain", action="store_true", help="also measure adherence and the text-gain ceiling")
    parser.add_argument("--prior-samples", type=int, default=48, help="draws without text for the ceiling")
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
            label_fraction=args.label_fraction,
        )
        if args.text_gain:
            gain_config = TextGainConfig(
                num_samples=args.samples,
                prior_samples=args.prior_samples,
                steps=args.steps,
                guidance_weight=args.cfg,
                max_windows=args.windows,
                label_fraction=args.label_fraction,
            )
            results[name]["text_gain"] = text_gain_table(module, args.data, gain_config, progress=True)
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
    if args.text_gain:
        _print_text_gain(results, args.samples, args.prior_samples)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=2)


def _print_text_gain(results: dict, samples: int, prior_samples: int) -> None:
    """The adherence and ceiling table (`text_gain_table`), one row per checkpoint and agent group."""
    print(
        f"\nprompt adherence (share of samples showing the prompt's facts) and the ceiling: minADE over the "
        f"first {samples} of {prior_samples} draws without text that show them"
    )
    print(
        "| model | agents | adherence, no text | adherence, text | minADE no text | minADE text | "
        "minADE ceiling | text gain | ceiling gain |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    )
    for name, r in results.items():
        g = r["text_gain"]
        for group in ("prompted", "checked"):
            if not g.get(f"{group}_agents"):
                continue
            adherence = (
                (f"{g['checked_adherence_no_text']:.3f}", f"{g['checked_adherence_text']:.3f}")
                if group == "checked"
                else ("", "")
            )
            print(
                f"| {name} ({group}) | {int(g[f'{group}_agents'])} | {adherence[0]} | {adherence[1]} | "
                f"{g[f'{group}_min_ade_no_text']:.3f} | {g[f'{group}_min_ade_text']:.3f} | "
                f"{g[f'{group}_min_ade_ceiling']:.3f} | {100 * g[f'{group}_text_gain']:.1f} % | "
                f"{100 * g[f'{group}_ceiling_gain']:.1f} % |"
            )


if __name__ == "__main__":
    main()
