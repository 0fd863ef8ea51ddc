"""Timing in words, measured on real episodes (docs/testing.md, 'Timing in words, measured'): for each case of a
suite whose prompt asks a cut-in or a braking lead, run each seed with a planner as ego and report when the staged
behaviour started (the simulation's report), when the prompted agent first entered the ego's lane ahead of it (its
centre within 1.75 m of the ego's heading line, ahead of it) and, for a braking lead, the bumper gap when it began to
brake (its judge's figure). Run it on a timed and an untimed copy of the same prompt to compare.

    python benchmarks/timing_words.py SUITE [--planner idm] [--seeds 4] [--cases NAME,...]
"""

from __future__ import annotations

import tempfile
from typing import Any

import numpy as np
from suite_args import run, suite_from_args

from langtraj.scenario.types import StateField
from langtraj.sim.staging import starts_of
from langtraj.suites import RunOptions
from langtraj.suites.episode import run_episode
from langtraj.suites.runner import episode_tasks

IN_LANE_M = 1.75


def entered(played: Any, ego: int, agent: int) -> float | None:
    """Seconds after the start when `agent`'s centre first came within `IN_LANE_M` of the ego's heading line, ahead
    of the ego, or None."""
    ids = played.agents.ids.tolist()
    if ego not in ids or agent not in ids:
        return None
    e, a, states, valid = ids.index(ego), ids.index(agent), played.agents.states, played.agents.valid
    for t in range(int(played.current_index) + 1, played.num_steps):
        if not (valid[e, t] and valid[a, t]):
            continue
        heading = states[e, t, StateField.HEADING]
        dx = states[a, t, StateField.X] - states[e, t, StateField.X]
        dy = states[a, t, StateField.Y] - states[e, t, StateField.Y]
        along = dx * np.cos(heading) + dy * np.sin(heading)
        across = -dx * np.sin(heading) + dy * np.cos(heading)
        if along > 0 and abs(across) <= IN_LANE_M:
            return (t - int(played.current_index)) * 0.1
    return None


def main() -> int:
    suite, args = suite_from_args(__doc__.splitlines()[0], seeds=4)
    with tempfile.TemporaryDirectory() as out:
        for task in episode_tasks(suite, RunOptions(out=out, planner=args.planner, video=False)):
            seen: dict[str, Any] = {}

            def watch(env: Any, seen: dict[str, Any] = seen) -> None:
                seen["played"], seen["report"] = env.unwrapped.played(), env.unwrapped.simulation_report()

            result = run_episode(task, watch=watch)
            agent = next((p["agent"] for p in result.prompts if p.get("agent") is not None), None)
            if "played" not in seen or agent is None or result.ego is None:
                print(f"{task.label}: {result.status} (not measured)")
                continue
            start = starts_of(seen["report"]).get(agent)
            began = None if start is None else start.seconds
            measures = {m["name"]: m["realised"] for p in result.prompts for m in p.get("measures", [])}
            gap = measures.get("gap ahead when braking began")
            lane = entered(seen["played"], result.ego, agent)
            print(
                f"{task.label}: {result.status}; started {began} s; in the ego's lane ahead from {lane} s"
                + ("" if gap is None else f"; gap when braking began {gap} m"),
                flush=True,
            )
    return 0


if __name__ == "__main__":
    run(main)
