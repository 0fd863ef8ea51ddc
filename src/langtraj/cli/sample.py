"""`langtraj sample SCENARIO --checkpoint CKPT [--prompt "@12 ..."] --out OUT [--samples N] [--index I]`.

Open-loop futures from a trained model, rendered top-down (OUT: .mp4, .gif or .png; with several
samples, one file per sample named OUT_s0, OUT_s1, ...). `--npz` also saves the sampled world states.

See README.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("sample", help="open-loop samples of a trained model on a scenario, rendered")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario file (WOMD TFRecord, ScenarioNet .pkl)")
    p.add_argument("--checkpoint", required=True, type=Path, help="trained checkpoint (.ckpt)")
    p.add_argument("--out", required=True, type=Path, help="video or image to write (.mp4, .gif, .png)")
    p.add_argument("--prompt", help='text for some agents, naming them by track id: "@12 yields to @7"')
    p.add_argument("--index", type=int, default=0, help="scenario in the file (default 0)")
    p.add_argument("--samples", type=int, default=1, help="futures to draw (default 1)")
    p.add_argument("--steps", type=int, default=10, help="DDIM steps (default 10)")
    p.add_argument("--guidance-weight", type=float, default=0.0, help="classifier-free guidance w (-1: no text)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--npz", type=Path, help="also save the samples' world states here")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from langtraj.errors import InputError
    from langtraj.fileio import atomic_path
    from langtraj.model.checkpoint import load_model
    from langtraj.scenario.io import read_scenario
    from langtraj.sim.open_loop import sample_open_loop
    from langtraj.viz import RenderConfig, save_png, save_video

    if args.out.suffix.lower() not in (".mp4", ".gif", ".png"):
        raise InputError("expected a .mp4, .gif or .png output", path=args.out)
    if args.samples < 1:
        raise InputError(f"--samples must be >= 1, got {args.samples}", where="arguments")
    scenario = read_scenario(args.scenario, args.index)
    model, data = load_model(args.checkpoint)
    result = sample_open_loop(
        model,
        scenario,
        data,
        prompt=args.prompt,
        num_samples=args.samples,
        steps=args.steps,
        guidance_weight=args.guidance_weight,
        seed=args.seed,
    )
    config = RenderConfig(highlight_ids=result.conditioned, show_ids=True)
    outputs = (
        [args.out]
        if args.samples == 1
        else [args.out.with_name(f"{args.out.stem}_s{s}{args.out.suffix}") for s in range(args.samples)]
    )
    for s, path in enumerate(outputs):
        shown = result.scenario_with(scenario, s)
        if path.suffix.lower() == ".png":
            save_png(shown, scenario.num_steps - 1, path, config)
        else:
            save_video(shown, path, config, progress=False)
    if args.npz:
        with atomic_path(args.npz) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, agents=scenario.agents.ids[result.agents], states=result.states.astype(np.float32))
    print(f"{len(outputs)} sample(s) of {len(result.agents)} agents -> {', '.join(map(str, outputs))}")
    return 0
