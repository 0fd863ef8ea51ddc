"""`langtraj render FILE --out OUT`: a top-down PNG of one step, or an MP4/GIF of a scene or window. See README.md."""

from __future__ import annotations

import argparse
from pathlib import Path

from langtraj.errors import InputError
from langtraj.scenario.io import read_scenario
from langtraj.scenario.windowing import WindowSpec, nth_window


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "render",
        help="render a scenario top-down to PNG (one step) or MP4/GIF (all steps)",
        description="Render a scenario top-down. OUT's suffix picks the output: .png draws one step "
        "(--step, default the current step); .mp4 or .gif animate the whole scene, or one 91-step "
        "window of it with --window.",
    )
    p.add_argument("file", metavar="FILE")
    p.add_argument("--out", required=True, help="output .png, .mp4 or .gif")
    p.add_argument("--index", type=int, default=0, help="which scenario of FILE (default 0)")
    p.add_argument("--window", type=int, metavar="W", help="render only window W (11 + 80 steps)")
    p.add_argument("--stride", type=int, help="step offset between window starts (default 91)")
    p.add_argument("--step", type=int, help="step to draw for PNG output (default: the current step)")
    p.add_argument("--follow", type=int, metavar="ID", help="camera follows this track id")
    p.add_argument("--extent", type=float, default=80.0, help="view width in metres when following")
    p.add_argument("--highlight", type=int, nargs="*", default=[], metavar="ID", help="track ids to highlight")
    p.add_argument("--ids", action="store_true", help="label agents with their track ids")
    p.add_argument("--size", type=int, default=800, help="image width and height in pixels")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from langtraj.viz import RenderConfig, save_png, save_video  # matplotlib import only when rendering

    if args.index < 0:
        raise InputError(f"--index must be >= 0, got {args.index}")
    scenario = read_scenario(args.file, args.index)
    if args.window is not None:
        try:
            scenario = nth_window(scenario, args.window, WindowSpec(stride=args.stride))
        except InputError as exc:
            raise exc.located(path=args.file, where="--window") from None
    config = RenderConfig(
        size_px=args.size,
        follow_track_id=args.follow,
        view_extent_m=args.extent,
        show_ids=args.ids,
        highlight_ids=tuple(args.highlight),
    )
    out = Path(args.out)
    if out.suffix.lower() == ".png":
        step = scenario.current_index if args.step is None else args.step
        save_png(scenario, step, out, config)
        print(f"wrote {out} (step {step} of {scenario.scenario_id})")
        return 0
    frames = save_video(scenario, out, config, progress=not args.no_progress)
    print(f"wrote {out} ({frames} frames of {scenario.scenario_id})")
    return 0
