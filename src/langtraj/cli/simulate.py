"""`langtraj simulate SCENARIO [--checkpoint CKPT] [--prompt "@12 yields to @7"]... [--adversary ID --target ID]
[--guidance NAME=WEIGHT]... [--rollouts R] [--seed S] --out DIR`.

Closed-loop simulation of one scene. DIR receives `rollouts.npz` (for `langtraj evaluate` and the
WOSAC submission writer), `rollout0.mp4` (rollout 0, prompted agents highlighted, the prompt as caption,
the target of each prompt marked on the map) and `summary.json` (per-agent collision, offroad and distance
travelled; timing). Without `--checkpoint` the checkpoint shipped with LangTraj is used. Every input is checked
before anything is written. A prompt steers by its text, by guidance toward the target the map gives the behaviour
read from it, and by adherence-first candidate selection (`--no-prompt-text`, `--no-prompt-guidance`,
`--no-prompt-selection` switch each off); the summary's `prompt` says what was read and what steered. A prompt whose
reading asks for a manoeuvre the map does not allow (a turn or lane change with no lane for it, ...) is simulated as
typed, and warned about on stderr once simulated (and in the summary's `prompt_warnings`): the policy reads each
prompt once and asks the map about that reading at the start of the simulation, with the map index it steers by.

See README.md.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from langtraj.sim.config import SimConfig, SimRequest, add_options, from_args


def _policies() -> str:
    from langtraj.sim.policies import POLICIES

    return ", ".join(n for n in POLICIES.names() if n != "langtraj")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("simulate", help="closed-loop simulation of a scene (rollouts, video, summary)")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario file (WOMD TFRecord, ScenarioNet .pkl)")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--index", type=int, default=0, help="scenario in the file (default 0)")
    add_options(p, SimRequest, policies=_policies())  # one option per field, its flag and help in the field
    add_options(p, SimConfig)
    p.add_argument("--no-video", action="store_true", help="skip the video")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from langtraj.fileio import atomic_path
    from langtraj.scenario.io import read_scenario
    from langtraj.sim.engine import simulate
    from langtraj.sim.setup import build_policy
    from langtraj.sim.summary import simulation_summary
    from langtraj.viz import RenderConfig, marks_from_prompt, save_video

    config = from_args(SimConfig, args)
    scenario = read_scenario(args.scenario, args.index)
    request = from_args(SimRequest, args)
    policy, described = build_policy(scenario, request)  # every check happens here, before any write
    result = simulate(scenario, policy, config)
    warnings = result.report.get("prompt_warnings", [])  # what the policy's reading of the prompts asks in vain
    for line in warnings:
        print(f"warning: {line}", file=sys.stderr)
    summary = simulation_summary(result, policy=request.policy, **described) | {"prompt_warnings": warnings}
    print("; ".join(f"{len(ids)} agents moved by {name}" for name, ids in summary["agents_by_policy"].items()))
    for line in summary.get("prompt", {}).get("steering", []):
        print(f"prompt: {line}")
    if summary["reads_future_log"]:
        print("WARNING: some agents replayed their logged future: a baseline, not a valid WOSAC simulation")
    args.out.mkdir(parents=True, exist_ok=True)
    result.rollouts.save(args.out / "rollouts.npz")
    if not args.no_video:
        caption = "; ".join(request.prompts) or (
            "collision guidance" if request.adversary is not None else request.policy
        )
        highlight = tuple(described.get("prompted_ids", ())) + tuple(
            i for i in (request.adversary, request.target) if i is not None
        )
        marks = marks_from_prompt(summary.get("prompt") or {})
        render = RenderConfig(highlight_ids=highlight, show_ids=True, caption=caption[:120], marks=marks)
        save_video(result.scenario(0), args.out / "rollout0.mp4", render, progress=False)
    with atomic_path(args.out / "summary.json") as tmp:
        tmp.write_text(json.dumps(summary, indent=2))
    print(
        f"{config.rollouts} rollouts of {len(result.rollouts.object_id)} agents in {result.seconds:.1f} s; "
        f"collision rate {summary['collision_rate']:.3f} -> {args.out}"
    )
    return 0
