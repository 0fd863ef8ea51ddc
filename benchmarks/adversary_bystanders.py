"""Do prompted agents drive like drivers? (docs/testing.md, 'Adversaries at 10 Hz, behind the traffic, measured'): for
each case of a suite and each seed, run the episode as written and again with its prompts removed (the same agents,
the model driving them unprompted), and count, for each prompted agent, the episodes in which it collided with a
bystander (anyone but the ego and the agent its behaviour is toward) and in which it left the road, from the
episode's traffic events (`suites.traffic`). The issue's target: prompted within 0.02 of unprompted.

    python benchmarks/adversary_bystanders.py SUITE [--planner idm] [--seeds 2] [--cases NAME,...]
"""

from __future__ import annotations

import collections
import dataclasses
import tempfile
from typing import Any

from suite_args import run, suite_from_args

from langtraj.suites import RunOptions
from langtraj.suites.episode import run_episode
from langtraj.suites.runner import episode_tasks


def faults_of(traffic: dict[str, Any] | None, agent: int, spared: set[int]) -> tuple[bool, bool]:
    """Whether `agent` collided with anyone outside `spared`, and whether it left the road, in an episode's traffic
    events."""
    bumped = offroad = False
    for event in (traffic or {}).get("events", []):
        if event["kind"] == "offroad" and event["agent"] == agent:
            offroad = True
        if event["kind"] == "collision" and agent in (event["agent"], event["with"]):
            partner = event["with"] if event["agent"] == agent else event["agent"]
            bumped = bumped or partner not in spared
    return bumped, offroad


def main() -> int:
    suite, args = suite_from_args(__doc__.splitlines()[0], seeds=2)
    unprompted = dataclasses.replace(suite, cases=tuple(dataclasses.replace(c, prompts=()) for c in suite.cases))
    tally: dict[str, list[int]] = collections.defaultdict(lambda: [0, 0, 0, 0, 0])  # n, bump, bump0, off, off0
    with tempfile.TemporaryDirectory() as out:
        options = RunOptions(out=out, planner=args.planner, video=False)
        for task, bare in zip(episode_tasks(suite, options), episode_tasks(unprompted, options), strict=True):
            result, alone = run_episode(task), run_episode(bare)
            for prompt in result.prompts:
                agent = prompt.get("agent")
                if agent is None or result.ego is None:
                    continue
                spared = {result.ego} | ({prompt["other"]} if prompt.get("other") is not None else set())
                with_prompt, without = faults_of(result.traffic, agent, spared), faults_of(alone.traffic, agent, spared)
                row = tally[str(prompt.get("behaviour"))]
                row[0] += 1
                row[1] += with_prompt[0]
                row[2] += without[0]
                row[3] += with_prompt[1]
                row[4] += without[1]
                print(
                    f"{task.label}: @{agent} prompted: bystander contact {with_prompt[0]}, off-road {with_prompt[1]};"
                    f" unprompted: {without[0]}, {without[1]}",
                    flush=True,
                )
    print("\n| behaviour | agents | bystander contacts, prompted | unprompted | off-road, prompted | unprompted |")
    print("| --- | --- | --- | --- | --- | --- |")
    total = [0, 0, 0, 0, 0]
    for name, row in sorted(tally.items()):
        total = [a + b for a, b in zip(total, row, strict=True)]
        print(f"| {name} | {row[0]} | " + " | ".join(f"{v / row[0]:.2f}" for v in row[1:]) + " |")
    if total[0]:
        print(f"| all | {total[0]} | " + " | ".join(f"{v / total[0]:.2f}" for v in total[1:]) + " |")
    return 0


if __name__ == "__main__":
    run(main)
