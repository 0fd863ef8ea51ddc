"""`langtraj interdrive`: build, export, import and summarize InterDrive labels and prompts (docs/interdrive.md).

`build` takes scenario files or folders of them (searched recursively).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from langtraj.errors import InputError


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "interdrive",
        help="InterDrive labels and prompts: build, export, import, stats",
        description="Label scenario windows (single-agent heuristics, interactions from SUMO ground truth "
        "or the rule-based detector), draw compositional prompt pools, and exchange human labels in the "
        "InterDrive JSON layout.",
    )
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")

    build = sub.add_parser("build", help="label scenario files into a dataset folder (shards + manifest)")
    build.add_argument(
        "scenarios",
        nargs="+",
        metavar="SCENARIOS",
        help="scenario files (WOMD TFRecord, ScenarioNet .pkl), or folders searched recursively",
    )
    build.add_argument("--out", required=True, help="dataset folder (labels/*.jsonl, manifest.json)")
    build.add_argument("--seed", type=int, default=0, help="prompt sampling seed")
    build.add_argument("--prompts-per-agent", type=int, default=3, help="prompts drawn per labelled agent")
    build.add_argument("--no-detector", action="store_true", help="skip the detector on scenes with SUMO events")
    build.add_argument("--workers", type=int, default=1, help="scenario files labelled at once")
    build.add_argument("--llm-url", help="OpenAI-compatible API base adding LLM rephrasings (off by default; cached)")
    build.add_argument("--llm-model", default="gpt-4o-mini", help="model name for --llm-url")
    build.add_argument("--executor", default="process", choices=("process", "ray"), help="where shards run")
    build.set_defaults(func=run_build)

    export = sub.add_parser("export", help="write one InterDrive {scenario_id}.json per labelled window")
    export.add_argument("dataset", help="dataset folder")
    export.add_argument("--out", required=True, help="folder for the JSON files")
    export.set_defaults(func=run_export)

    imp = sub.add_parser("import", help="merge InterDrive JSON files into a dataset as human labels")
    imp.add_argument("json_dir", help="folder of {scenario_id}.json files")
    imp.add_argument("--into", required=True, help="dataset folder")
    imp.set_defaults(func=run_import)

    show = sub.add_parser("show", help="render one labelled window with its labels and prompts to PNG")
    show.add_argument("dataset", help="dataset folder")
    show.add_argument("scenario_id", help="window id (see the dataset's labels/*.jsonl)")
    show.add_argument("--out", required=True, help="PNG path")
    show.add_argument("--agents", help="comma-separated track ids to describe (default: the interacting ones)")
    show.set_defaults(func=run_show)

    stats = sub.add_parser("stats", help="print label counts and plot them per type and subtype")
    stats.add_argument("dataset", help="dataset folder")
    stats.add_argument("--plot", help="PNG path (default: DATASET/stats.png)")
    stats.add_argument("--source", help="plot only one label source (ground_truth, detector, human)")
    stats.set_defaults(func=run_stats)


def run_build(args: argparse.Namespace) -> int:
    from langtraj.interdrive.dataset import BuildConfig, build_dataset
    from langtraj.scenario.io import expand_scenario_paths

    for name, value in (("--workers", args.workers), ("--prompts-per-agent", args.prompts_per_agent)):
        if value < 1:
            raise InputError(f"must be at least 1, got {value}", where=name)
    config = BuildConfig(
        seed=args.seed,
        prompts_per_agent=args.prompts_per_agent,
        detector=not args.no_detector,
        llm_url=args.llm_url,
        llm_model=args.llm_model,
    )
    sources = expand_scenario_paths(args.scenarios)
    manifest = build_dataset(sources, Path(args.out), config, args.workers, args.executor)
    interactions = sum(sum(s["interactions"].values()) for s in manifest["shards"])
    prompts = sum(s["prompts"] for s in manifest["shards"])
    print(f"{manifest['windows']} windows, {interactions} interaction labels, {prompts} prompts -> {args.out}")
    return 0


def run_export(args: argparse.Namespace) -> int:
    from langtraj.interdrive.exchange import export_json

    summary = export_json(Path(args.dataset), Path(args.out))
    print(f"{summary.written} scenes written to {args.out} ({summary.skipped} windows without an interacting pair)")
    return 0


def run_import(args: argparse.Namespace) -> int:
    from langtraj.interdrive.exchange import import_json

    updated = import_json(Path(args.json_dir), Path(args.into))
    print(f"{updated} windows updated with human labels in {args.into}")
    return 0


def run_stats(args: argparse.Namespace) -> int:
    from langtraj.interdrive.dataset import read_manifest
    from langtraj.interdrive.labels import LabelSource
    from langtraj.interdrive.stats import dataset_stats, format_stats, plot_stats

    dataset = Path(args.dataset)
    read_manifest(dataset)
    if args.source is not None and args.source not in {s.value for s in LabelSource}:
        raise InputError(
            f"unknown source {args.source!r}; known: {', '.join(s.value for s in LabelSource)}", where="--source"
        )
    stats = dataset_stats(dataset)
    print(format_stats(stats))
    plot = Path(args.plot) if args.plot else dataset / "stats.png"
    plot_stats(stats, plot, args.source)
    print(f"plot -> {plot}")
    return 0


def run_show(args: argparse.Namespace) -> int:
    from langtraj.interdrive.dataset import load_window
    from langtraj.interdrive.describe import describe, focus_agents
    from langtraj.interdrive.exchange import records_by_id
    from langtraj.viz import RenderConfig
    from langtraj.viz.annotated import save_annotated_png

    records = records_by_id(Path(args.dataset))
    record = records.get(args.scenario_id)
    if record is None:
        raise InputError(f"no window {args.scenario_id!r} in {args.dataset}", where="scenario_id")
    agents = _track_ids(args.agents, record.track_ids) if args.agents else focus_agents(record)
    lines = describe(record, agents)
    save_annotated_png(
        load_window(record), lines, Path(args.out), RenderConfig(highlight_ids=tuple(agents), show_ids=True)
    )
    print("\n".join(lines))
    print(f"-> {args.out}")
    return 0


def _track_ids(text: str, known: tuple[int, ...]) -> tuple[int, ...]:
    try:
        ids = tuple(int(t) for t in text.split(","))
    except ValueError:
        raise InputError(f"expected comma-separated track ids, got {text!r}", where="--agents") from None
    unknown = [t for t in ids if t not in known]
    if unknown:
        raise InputError(f"track {unknown[0]} is not in this window", where="--agents")
    return ids
