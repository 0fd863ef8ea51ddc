"""Seconds for 32 closed-loop rollouts of 8 s (K = 5 DDIM steps, replanning at 1 Hz) of a 64-agent and a
128-agent scene and a whole real WOMD scene, in the paper's setting (no guidance), with `langtraj
simulate`'s defaults (on-road and no-collision guidance, per-agent selection) and with a prompt, and the
ratios, on this machine's CPU (or a GPU when one is present).

The scenes come from the real WOMD scene 2a1e44d405a6833f (ScenarioNet pickle in ../shared/data/real,
211 tracks, 66 of them valid at the current step). Its 64 most important sim agents make the 64-agent
scene; no real file here has 128 sim agents, so the 128-agent scene is the 64-agent one plus a copy of
its agents and its map 1 km east (new track and map feature ids; until 2026-11-25 the copy had no map,
which left the copied agents nowhere near a road edge for the on-road guidance). The model drives every
sim agent (samples sized for them, `SampleConfig.for_agents`), as in every scored simulation, attending
locally unless --dense-attention. The real scene is 2a1e44d405a6833f whole (66 sim agents, all driven).
Medians over --repeats runs; each repeat runs every setting in turn (a shared VM's speed drifts within minutes),
and a ratio is the median of the repeats' own ratios.

    python benchmarks/simulate_speed.py [--scenes 64 128 real] [--settings paper defaults prompt]
        [--checkpoint CKPT] [--candidates 4] [--repeats 3] [--rollouts 32] [--guided-steps N]
        [--prompt "@{id} slows down"] [--dense-attention] [--compile] [--warm-steps N] [--refresh-map]
        [--hard-constraints N] [--[no-]hold-parked] [--rolling]

With --compile the denoiser is compiled (`LangTraj.compile_steps`, as `langtraj simulate --compile`) and one
untimed simulation per scene and setting compiles it first. --warm-steps, --rolling and --refresh-map time the replan
options of the same names (`langtraj simulate`; docs/simulation.md).
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT.parent / "shared" / "data" / "real" / "sd_training.tfrecord-00000-of-01000_2a1e44d405a6833f.pkl"


def cut_scene(scenario, num_agents: int):
    """The scenario with only its `num_agents` most important sim agents (every other track dropped)."""
    from langtraj.scenario.selection import prioritized_agents

    keep = np.sort(prioritized_agents(scenario, num_agents))
    if len(keep) < num_agents:
        raise SystemExit(f"{SCENE.name} has only {len(keep)} sim agents, fewer than {num_agents}")
    agents = scenario.agents
    rows = {int(r): i for i, r in enumerate(keep)}
    sdc = rows.get(int(scenario.sdc_index), -1)
    cut = replace(
        agents,
        ids=agents.ids[keep],
        types=agents.types[keep],
        states=agents.states[keep],
        valid=agents.valid[keep],
        tracks_to_predict=np.array([rows[int(t)] for t in agents.tracks_to_predict if int(t) in rows], np.int64),
        prediction_difficulty=None,
        objects_of_interest=np.array([rows[int(t)] for t in agents.objects_of_interest if int(t) in rows], np.int64),
    )
    return replace(scenario, agents=cut, sdc_index=sdc)


def _shifted_map(road_map, offset: float, id_shift: int):
    """The map's features moved `offset` m east, every feature id (and each reference to one) + `id_shift`."""
    from langtraj.scenario.model import MapFeature, RoadMap

    def shift_ids(ids):
        return tuple(int(i) + id_shift for i in ids)

    def boundary(b):
        return replace(b, boundary_feature_id=b.boundary_feature_id + id_shift)

    def neighbour(n):
        return replace(n, feature_id=n.feature_id + id_shift, boundaries=tuple(boundary(b) for b in n.boundaries))

    def moved(points):
        if points is None:
            return None
        points = points.copy()
        points[:, 0] += offset
        return points

    copies = [
        MapFeature(
            **{
                **vars(f),
                "id": f.id + id_shift,
                "points": moved(f.points),
                "polygon": moved(f.polygon),
                "entry_lanes": shift_ids(f.entry_lanes),
                "exit_lanes": shift_ids(f.exit_lanes),
                "controlled_lanes": shift_ids(f.controlled_lanes),
                "left_neighbors": tuple(neighbour(n) for n in f.left_neighbors),
                "right_neighbors": tuple(neighbour(n) for n in f.right_neighbors),
                "left_boundaries": tuple(boundary(b) for b in f.left_boundaries),
                "right_boundaries": tuple(boundary(b) for b in f.right_boundaries),
            }
        )
        for f in road_map
    ]
    return RoadMap(tuple(road_map) + tuple(copies))


def doubled(scenario, offset: float = 1000.0):
    """The scenario with a copy of every track and of the map `offset` m east (ids shifted past the
    largest), so every agent of the copy drives on its own copy of the road."""
    agents = scenario.agents
    shifted = agents.states.copy()
    shifted[..., 0] += offset
    n = agents.num_agents
    both = replace(
        agents,
        ids=np.concatenate([agents.ids, agents.ids + int(agents.ids.max()) + 1]),
        types=np.concatenate([agents.types, agents.types]),
        states=np.concatenate([agents.states, shifted]),
        valid=np.concatenate([agents.valid, agents.valid]),
        tracks_to_predict=agents.tracks_to_predict,
        objects_of_interest=agents.objects_of_interest,
    )
    assert both.num_agents == 2 * n
    id_shift = max(f.id for f in scenario.road_map) + 1
    return replace(scenario, agents=both, road_map=_shifted_map(scenario.road_map, offset, id_shift))


SETTINGS = ("paper", "defaults", "prompt")
"""The paper's setting (no guidance, `min_collision`), `langtraj simulate`'s defaults (on-road and
no-collision guidance, `per_agent` selection), and the defaults with a prompt on the most important agent."""


def scenes(full, counts):
    """(name, scene) of each benchmark scene: the real scene cut to 16-64 agents, doubled for 128, and the
    whole real scene."""
    for count in counts:
        if count == "real":
            yield f"real WOMD {full.scenario_id}", full
        elif int(count) <= 64:
            yield f"{count} agents", cut_scene(full, int(count))
        else:
            yield f"{count} agents", doubled(cut_scene(full, int(count) // 2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--checkpoint", help="default: the shipped checkpoint")
    parser.add_argument("--candidates", type=int, default=4, help="candidates per replan (paper: 64 on a GPU)")
    parser.add_argument("--rollouts", type=int, default=32)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--scenes", nargs="+", default=["64", "128", "real"], choices=["16", "32", "64", "128", "real"])
    parser.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=SETTINGS)
    parser.add_argument("--guided-steps", type=int, help="the defaults' guided denoising steps (default: simulate's)")
    parser.add_argument("--prompt", default="@{id} slows down", help="the prompt ({id}: the most important agent)")
    parser.add_argument("--dense-attention", action="store_true", help="dense attention (default: local, as simulate)")
    parser.add_argument("--compile", action="store_true", help="compile the denoiser; an untimed run compiles it")
    parser.add_argument("--warm-steps", type=int, help="replans warm-started at the last N denoising steps")
    parser.add_argument("--refresh-map", action="store_true", help="each replan chooses its own map")
    parser.add_argument(
        "--rolling", action="store_true", help="rolling plans, one network call per replan (a rolling checkpoint)"
    )
    parser.add_argument(
        "--hard-constraints", type=int, help="the defaults' projection at the last N denoising steps (0: off)"
    )
    parser.add_argument(
        "--hold-parked", action=argparse.BooleanOptionalAction, default=None, help="the defaults hold parked agents"
    )
    args = parser.parse_args()
    if not SCENE.is_file():
        sys.exit(f"benchmark scene not found: {SCENE}")

    from langtraj.model.checkpoint import load_model
    from langtraj.scenario.io import read_scenario
    from langtraj.sim.checkpoints import shipped_checkpoint
    from langtraj.sim.config import SimRequest
    from langtraj.sim.engine import SimConfig, simulate
    from langtraj.sim.policies import LangTrajPolicy, hard_constraints, model_agents
    from langtraj.sim.prompts import merged_prompt

    device = "cuda" if torch.cuda.is_available() else "cpu"
    checkpoint = args.checkpoint or shipped_checkpoint()
    model, data = load_model(checkpoint)
    model.to(device)
    if args.compile:
        model.compile_steps(training=False)
    base = SimRequest(
        candidates=args.candidates,
        steps=5,
        dense_attention=args.dense_attention,
        warm_steps=args.warm_steps,
        refresh_map=args.refresh_map,
        rolling=args.rolling,
    )
    paper = replace(
        base, on_road=0.0, no_collision=0.0, selector="min_collision", hard_constraints=0, hold_parked=False
    )
    defaults = replace(
        base, guided_steps=args.guided_steps, hard_constraints=args.hard_constraints, hold_parked=args.hold_parked
    )
    resolved = LangTrajPolicy(model, data, defaults).request  # checked, with simulate's defaults
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, torch threads "
        f"{torch.get_num_threads()}, device {device}; checkpoint {Path(checkpoint).name} "
        f"(trained on {data.max_agents}-agent scenes; drives every sim agent); {args.rollouts} rollouts x 8 s, "
        f"K = 5, replanning at 1 Hz, {args.candidates} candidates per replan, "
        f"{'dense' if args.dense_attention else 'local'} attention, "
        f"denoiser {'compiled' if args.compile else 'eager'}, warm steps {args.warm_steps}, rolling {args.rolling}, "
        f"map {'each replan' if args.refresh_map else 'of the start'}; defaults guided at the last "
        f"{resolved.guided_steps} of 5 denoising steps, hard constraints {hard_constraints(args.hard_constraints, 5)}, "
        f"hold parked {resolved.hold_parked}; medians of {args.repeats} runs"
    )

    def policy(setting: str, scene) -> LangTrajPolicy:
        if setting == "paper":
            return LangTrajPolicy(model, data, paper)
        prompt = None
        if setting == "prompt":
            first = int(scene.agents.ids[model_agents(scene)[0]])
            prompt = merged_prompt(scene, [args.prompt.format(id=first)])
        return LangTrajPolicy(model, data, defaults, prompt=prompt)

    rows = []
    for name, scene in scenes(read_scenario(SCENE), args.scenes):
        if args.compile:  # compiling for this scene's shapes is not what is timed
            for setting in args.settings:
                simulate(scene, policy(setting, scene), SimConfig(rollouts=args.rollouts, seed=0))
        # Settings interleaved within each repeat, so that a shared VM's drifting speed (measured: the same run
        # from 35 to 50 s within the hour) falls on every setting alike, and ratios are taken repeat by repeat.
        times: dict[str, list[float]] = {setting: [] for setting in args.settings}
        for repeat in range(args.repeats):
            for setting in args.settings:
                result = simulate(scene, policy(setting, scene), SimConfig(rollouts=args.rollouts, seed=repeat))
                times[setting].append(result.seconds)
        driven = len(result.driven_ids)
        for setting, runs in times.items():
            listed = ", ".join(f"{t:.2f}" for t in runs)
            print(f"{name} ({driven} driven), {setting}: median {statistics.median(runs):.2f} s ({listed})")
        rows.append((name, times))
    print("\n| scene | " + " | ".join(args.settings) + " | defaults / paper | prompt / defaults |")
    print("|" + " --- |" * (len(args.settings) + 3))
    for name, times in rows:
        cells = [f"{statistics.median(times[s]):.1f} s" for s in args.settings]
        ratios = [_ratio(times, "defaults", "paper"), _ratio(times, "prompt", "defaults")]
        print(f"| {name} | " + " | ".join(cells + ratios) + " |")
    print("(ratios: the median over repeats of each repeat's ratio)")


def _ratio(times: dict[str, list[float]], top: str, bottom: str) -> str:
    if top not in times or bottom not in times:
        return "-"
    return f"{statistics.median(a / b for a, b in zip(times[top], times[bottom], strict=True)):.2f}"


if __name__ == "__main__":
    main()
