"""Seconds for one 8-s episode of the LangTraj environment (an ego under the IDM planner, every other agent driven
by LangTraj with `simulate`'s defaults, replanning at 1 Hz) against `langtraj simulate` of one rollout of the
same scene (every agent driven, the ego included), and their ratio: the issue's target is at most 2x.

Scenes: the real WOMD scenes in ../shared/data/real (the TFRecord and the two Waymo ScenarioNet pickles); the ego
is each scene's self-driving car. Both runs load the checkpoint once beforehand (not timed), then time reset or
policy building plus the whole episode; the episode's time includes observations, the planner and the per-step
safety figures. One untimed run of each first (lazy initialisation, GPU kernels); medians over --repeats runs
(seeds 0, 1, ...).

    python benchmarks/env_speed.py [--checkpoint CKPT] [--repeats 3] [--planner idm] [--device cuda] [--scenes ...]
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time
from pathlib import Path

import torch

from langtraj.env import LangTrajEnv
from langtraj.model.checkpoint import load_model
from langtraj.planners import load_planner, reset_planner
from langtraj.scenario.io import read_scenario
from langtraj.sim.checkpoints import shipped_checkpoint
from langtraj.sim.config import SimConfig, SimRequest
from langtraj.sim.engine import simulate
from langtraj.sim.setup import build_policy

REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"
SCENES = (
    "motion_data_one_scenario.tfrecord",
    "sd_training.tfrecord-00000-of-01000_2a1e44d405a6833f.pkl",
    "sd_training.tfrecord-00000-of-01000_8a346109094cd5aa.pkl",
)


def time_simulate(scenario, loaded, checkpoint, seed: int) -> float:
    tick = time.perf_counter()
    policy, _ = build_policy(scenario, SimRequest(checkpoint=checkpoint), loaded)
    simulate(scenario, policy, SimConfig(rollouts=1, seed=seed))
    return time.perf_counter() - tick


def time_episode(env: LangTrajEnv, planner_spec: str, seed: int) -> float:
    tick = time.perf_counter()
    planner = load_planner(planner_spec)()
    obs, info = env.reset(seed=seed)
    reset_planner(planner, obs, info)
    done = False
    while not done:
        obs, _, terminated, truncated, _ = env.step(planner.act(obs))
        done = terminated or truncated
    return time.perf_counter() - tick


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--checkpoint", type=Path)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--planner", default="idm")
    parser.add_argument("--device", default="cpu", help="where the model runs (cpu, cuda)")
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), help="files in --real")
    parser.add_argument("--real", type=Path, default=REAL, help="the folder of real scenes (../shared/data/real)")
    args = parser.parse_args()
    checkpoint = args.checkpoint or shipped_checkpoint()
    model, data = load_model(checkpoint)
    loaded = (model.to(args.device), data)
    gpu = torch.cuda.get_device_name() if args.device.startswith("cuda") else "none"
    print(f"machine: {platform.processor() or platform.machine()}, GPU {gpu}, torch {torch.__version__}, threads "
          f"{torch.get_num_threads()}; checkpoint {checkpoint.name}; planner {args.planner}")  # fmt: skip
    print("| scene | sim agents | simulate, 1 rollout (s) | env episode (s) | ratio |")
    print("| --- | --- | --- | --- | --- |")
    for name in args.scenes:
        scenario = read_scenario(args.real / name)
        env = LangTrajEnv(scenario, checkpoint=checkpoint, device=args.device)
        env._loaded = loaded  # the same model in memory for both
        time_simulate(scenario, loaded, checkpoint, 99)  # warm-up (lazy initialisation, GPU kernels), not timed
        time_episode(env, args.planner, 99)
        sim = [time_simulate(scenario, loaded, checkpoint, seed) for seed in range(args.repeats)]
        episode = [time_episode(env, args.planner, seed) for seed in range(args.repeats)]
        a, b = statistics.median(sim), statistics.median(episode)
        agents = int(scenario.agents.valid[:, scenario.current_index].sum())
        print(f"| {scenario.scenario_id} | {agents} | {a:.2f} | {b:.2f} | {b / a:.2f}x |")


if __name__ == "__main__":
    main()
