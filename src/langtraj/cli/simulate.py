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

from langtraj.sim.config import UNDRIVEN


def _policies() -> str:
    from langtraj.sim.policies import POLICIES

    return ", ".join(n for n in POLICIES.names() if n != "langtraj")


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("simulate", help="closed-loop simulation of a scene (rollouts, video, summary)")
    p.add_argument("scenario", metavar="SCENARIO", help="scenario file (WOMD TFRecord, ScenarioNet .pkl)")
    p.add_argument("--out", required=True, type=Path, help="output folder")
    p.add_argument("--index", type=int, default=0, help="scenario in the file (default 0)")
    p.add_argument("--policy", default="langtraj", help="a registered policy: langtraj (default), " + _policies())
    p.add_argument("--checkpoint", type=Path, help="trained checkpoint (default: the shipped one)")
    p.add_argument(
        "--prompt", action="append", default=[], help='text naming agents by track id: "@12 yields to @7" (repeatable)'
    )
    for lever, what in (
        ("text", "conditioning the model on the prompt's text"),
        ("guidance", "guidance toward the target the map gives the behaviour read from the prompt"),
        ("selection", "preferring, per prompted agent, the candidates that do what it asks"),
    ):
        p.add_argument(
            f"--no-prompt-{lever}",
            dest=f"prompt_{lever}",
            action="store_false",
            help=f"a prompt steers without {what} (on by default; docs/simulation.md, 'Prompts that steer')",
        )
    p.add_argument("--adversary", type=int, help="track id driven into --target by collision guidance")
    p.add_argument("--target", type=int, help="track id the adversary collides with")
    p.add_argument("--collision-weight", type=float, default=1.0, help="weight of the collision guidance (default 1)")
    p.add_argument(
        "--guidance",
        action="append",
        default=[],
        metavar="NAME=WEIGHT",
        help="extra guidance cost on every driven agent: no_collision, on_road, keep_lane (repeatable)",
    )
    p.add_argument(
        "--on-road",
        type=float,
        metavar="W",
        help="weight of the on-road guidance every driven agent gets (default 1, chosen by measurement; 0: off)",
    )
    p.add_argument(
        "--no-collision",
        type=float,
        metavar="W",
        help="weight per agent pair of the no-collision guidance between driven agents (default 1, chosen by "
        "measurement; 0: off; an --adversary and its --target are left out)",
    )
    p.add_argument(
        "--guided-steps",
        type=int,
        metavar="N",
        help="the on-road and no-collision guidance apply at the last N denoising steps (default: chosen by "
        "measurement, docs/experiments.md; --steps: every step)",
    )
    p.add_argument(
        "--warm-steps",
        type=int,
        metavar="N",
        help="each replan starts from the plan executed so far, noised to the last N of the --steps denoising "
        "steps (N network calls instead of --steps; docs/simulation.md, 'Warm-started replans'); default: fresh noise",
    )
    p.add_argument(
        "--rolling",
        action="store_true",
        help="keep one rolling plan per agent whose noise rises along the future and denoise it once per replan "
        "(a checkpoint trained with model.rolling_group; docs/simulation.md, 'Rolling plans')",
    )
    p.add_argument(
        "--temperature",
        type=float,
        default=1.0,
        metavar="T",
        help="scale the sampler's noise by T in (0, 2] (below 1: nearer the model's most likely future, less "
        "diverse; docs/simulation.md)",
    )
    p.add_argument(
        "--refresh-map",
        action="store_true",
        help="each replan chooses the model's map pieces around where the agents are then (default: the start's "
        "map for every replan; docs/simulation.md, 'The map at each replan')",
    )
    p.add_argument(
        "--hard-constraints",
        type=int,
        metavar="N",
        help="at the last N denoising steps, project every plan onto the road and out of overlap and refit its "
        "actions (docs/simulation.md, 'Hard constraints'; default: chosen by measurement; 0: off)",
    )
    p.add_argument(
        "--hold-parked",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="agents parked in the log (still through their history, off the travel lanes) stand still unless a "
        "prompt names them (default: chosen by measurement, docs/simulation.md)",
    )
    p.add_argument(
        "--selector",
        help="candidate selection: per_agent (default without guidance), min_guidance (default with it), "
        "min_collision (the paper's), min_collision_offroad, first",
    )
    p.add_argument(
        "--dense-attention",
        action="store_true",
        help="every driven agent attends to every agent and map piece (default: in scenes larger than the model's "
        "training scenes, each attends to a neighbourhood of the size it was trained on; docs/model.md)",
    )
    p.add_argument(
        "--compile",
        action="store_true",
        help="compile the denoiser with torch.compile (the first replan compiles, a minute or so: pays on a GPU, "
        "where a denoising step is bound by launching small kernels; docs/model.md)",
    )
    p.add_argument("--guidance-scale", type=float, default=1.0, help="step size alpha of reconstruction guidance")
    p.add_argument("--cfg", type=float, default=0.0, help="classifier-free guidance weight w (-1: ignore text)")
    p.add_argument("--rollouts", type=int, default=32, help="joint rollouts (default 32, as WOSAC)")
    p.add_argument(
        "--candidates", type=int, default=4, help="candidates sampled per replan (default 4; paper: 64 on a GPU)"
    )
    p.add_argument("--steps", type=int, default=5, help="DDIM steps per sample (default 5)")
    p.add_argument("--replan-s", type=float, default=1.0, help="seconds between replans (default 1)")
    p.add_argument(
        "--max-driven",
        type=int,
        metavar="N",
        help="the model drives only the N most important sim agents (default: every sim agent)",
    )
    p.add_argument(
        "--undriven",
        default="constant_velocity",
        choices=UNDRIVEN,
        help="how sim agents the model does not drive move: constant_velocity (default; reads no future) or log "
        "(replays the logged future: flagged, and refused by langtraj submit)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-video", action="store_true", help="skip the video")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from langtraj.fileio import atomic_path
    from langtraj.scenario.io import read_scenario
    from langtraj.sim.config import PromptLevers, SimConfig, SimRequest
    from langtraj.sim.engine import simulate
    from langtraj.sim.setup import build_policy
    from langtraj.sim.summary import simulation_summary
    from langtraj.viz import RenderConfig, marks_from_prompt, save_video

    config = SimConfig(rollouts=args.rollouts, replan_s=args.replan_s, seed=args.seed)
    scenario = read_scenario(args.scenario, args.index)
    request = SimRequest(
        policy=args.policy,
        checkpoint=args.checkpoint,
        prompts=tuple(args.prompt),
        adversary=args.adversary,
        target=args.target,
        collision_weight=args.collision_weight,
        guidance=tuple(args.guidance),
        guidance_scale=args.guidance_scale,
        cfg=args.cfg,
        candidates=args.candidates,
        steps=args.steps,
        max_driven=args.max_driven,
        undriven=args.undriven,
        selector=args.selector,
        on_road=args.on_road,
        no_collision=args.no_collision,
        dense_attention=args.dense_attention,
        guided_steps=args.guided_steps,
        warm_steps=args.warm_steps,
        rolling=args.rolling,
        temperature=args.temperature,
        refresh_map=args.refresh_map,
        hard_constraints=args.hard_constraints,
        hold_parked=args.hold_parked,
        compile=args.compile,
        levers=PromptLevers(args.prompt_text, args.prompt_guidance, args.prompt_selection),
    )
    policy, described = build_policy(scenario, request)  # every check happens here, before any write
    result = simulate(scenario, policy, config)
    warnings = result.report.get("prompt_warnings", [])  # what the policy's reading of the prompts asks in vain
    for line in warnings:
        print(f"warning: {line}", file=sys.stderr)
    summary = simulation_summary(result, policy=args.policy, **described) | {"prompt_warnings": warnings}
    print("; ".join(f"{len(ids)} agents moved by {name}" for name, ids in summary["agents_by_policy"].items()))
    for line in summary.get("prompt", {}).get("steering", []):
        print(f"prompt: {line}")
    if summary["reads_future_log"]:
        print("WARNING: some agents replayed their logged future: a baseline, not a valid WOSAC simulation")
    args.out.mkdir(parents=True, exist_ok=True)
    result.rollouts.save(args.out / "rollouts.npz")
    if not args.no_video:
        caption = "; ".join(args.prompt) or ("collision guidance" if args.adversary is not None else args.policy)
        highlight = tuple(described.get("prompted_ids", ())) + tuple(
            i for i in (args.adversary, args.target) if i is not None
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
