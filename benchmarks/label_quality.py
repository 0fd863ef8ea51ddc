"""Label quality on a synthesized corpus: heuristic labels and detected interactions against SUMO.

SUMO knows the answer for some single-agent labels, and this script scores the heuristics (which
see only positions and the map) against it, per agent over the future of each window:

- changing lanes (any, left, right): SUMO's lane-change output (`lane_change` events, direction);
  a change counts when SUMO's switch lies in the future at least 2 s before the window's end (agents
  whose only switches are in the last 2 s, in the 1 s before the current step, on junction-internal
  lanes (the labeler leaves lane choice inside a junction to the turn), or swerves undone within 3 s,
  are not scored for lane changes);
  a prediction must overlap the event in time, and its direction is read from its from/to positions
  (from the path's sideways motion against the heading 1 s before the label when both are "middle");
- stops (`static` label): SUMO's own speed at or below 0.3 m/s for at least 1 s;
- speeding up / slowing down: SUMO's speed rising / falling by at least `min_speed_change` over a run
  of at least `min_duration_s` whose acceleration stays beyond `accel_threshold` (the heuristics'
  thresholds, on SUMO's speed instead of speed from positions);
- turning left / right, going straight: the SUMO link direction of the vehicle's intersection
  passage in the future (agents with one whole passage in the future, not on a roundabout);
- pulling over: the drivers' executed pull-over decisions (`decision` events, `langtraj.synth.intents`)
  whose stop begins in the future at least 2 s before the window's end;
- crossing an intersection: a passage over an intersection's internal lanes (`junction_pass` with
  `intersection`) of at least 0.5 s in the future.

Interactions from the rule-based detector are scored against those mapped from SUMO's events
(`langtraj.interdrive.ground_truth`), per type; LangTraj's added subtypes (`taxonomy.ADDED_SUBTYPES`: cut-ins,
braking leads, red lights run), which SUMO's events never give, are left out.

    python benchmarks/label_quality.py [--corpus DIR | --windows 200 --seed 1 --workers 2]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections import defaultdict
from itertools import pairwise
from pathlib import Path

import numpy as np

from langtraj.interdrive.detector import detect_interactions
from langtraj.interdrive.evaluation import TypeCounts, add_counts, macro_f1, match_interactions
from langtraj.interdrive.ground_truth import ground_truth_interactions
from langtraj.interdrive.heuristics import HeuristicConfig, label_agents
from langtraj.interdrive.labels import AgentLabel
from langtraj.roads import MapIndex
from langtraj.runs import true_runs
from langtraj.scenario.io import read_scenarios
from langtraj.scenario.model import STEP_SECONDS, Scenario
from langtraj.scenario.types import AgentType, StateField
from langtraj.synth.factory import FactoryConfig, run_factory
from langtraj.synth.network import kind_names

STOP_SPEED = 0.3
SETTLE_STEPS = 20
"""A SUMO lane switch in the last 2 s of a window may not show in the motion yet, and one in the last 1 s
before the current step may show only after it: agents whose only switches are there are not scored for
lane changes."""
SWERVE_STEPS = 30
"""A SUMO lane change undone by the opposite change within 3 s is a swerve (the sublane model moves a car
just past a lane line and back), not a change from one lane to another: agents with only swerves are not
scored for lane changes."""
ORDER = {"rightmost": 0, "middle": 1, "leftmost": 2}
LEFT = ("l", "L")
RIGHT = ("r", "R")


class Scores:
    """Per-label counts of the single-agent comparisons, and how many vehicles were scored."""

    def __init__(self) -> None:
        self.single: dict[str, TypeCounts] = defaultdict(TypeCounts)
        self.agents = 0

    def add(self, key: str, truth: bool, predicted: bool) -> None:
        more = TypeCounts(int(truth and predicted), int(predicted and not truth), int(truth and not predicted))
        self.single[key] = self.single[key] + more


def _speed_truth(speed: np.ndarray, config: HeuristicConfig) -> dict[str, bool]:
    """Stops and speed changes from SUMO's speed (10 Hz) over the future."""
    min_steps = round(config.min_duration_s / STEP_SECONDS)
    accel = np.diff(speed) / STEP_SECONDS
    truth = {"static": any(b - a >= min_steps for a, b in true_runs(speed <= STOP_SPEED))}
    for key, sign in (("speeding_up", 1.0), ("slowing_down", -1.0)):
        hits = False
        for a, b in true_runs(sign * accel > config.accel_threshold):
            if b - a >= min_steps and sign * (speed[b] - speed[a]) >= config.min_speed_change:
                hits = True
        truth[key] = hits
    return truth


def _direction(label: AgentLabel, scenario: Scenario, agent: int) -> str:
    """left/right of a changing_lanes label: from its positions, else from the path's sideways motion."""
    a, b = ORDER.get(label.params["from"]), ORDER.get(label.params["to"])
    if a is not None and b is not None and a != b:
        return "left" if b > a else "right"
    states = scenario.agents.states[agent]
    start, end = label.start, min(label.end, scenario.num_steps - 1)
    heading = states[max(start - SETTLE_STEPS // 2, 0), StateField.HEADING]  # before the car turns into the change
    d = states[end, :2] - states[start, :2]
    return "left" if np.cos(heading) * d[1] - np.sin(heading) * d[0] > 0 else "right"


def _settled(changes: list) -> list:
    """Lane changes without the swerves: a change undone by the opposite change within `SWERVE_STEPS`."""
    changes = sorted(changes, key=lambda e: e.attributes["change_step"])
    swerves = set()
    for a, b in pairwise(changes):
        close = b.attributes["change_step"] - a.attributes["change_step"] <= SWERVE_STEPS
        if close and a.attributes["direction"] != b.attributes["direction"]:
            swerves |= {id(a), id(b)}
    return [e for e in changes if id(e) not in swerves]


def _score_lane_changes(scenario: Scenario, agent: int, events: list, mine: list[AgentLabel], scores: Scores) -> None:
    """Lane changes of one agent: any, and per direction (a predicted direction must overlap the event)."""
    current = scenario.current_index
    everything = [e for e in events if e.kind == "lane_change"]
    switches = _settled(everything)
    first, last = current - SETTLE_STEPS // 2, scenario.num_steps - SETTLE_STEPS

    def undecidable(e) -> bool:
        step = e.attributes["change_step"]
        return first <= step < current or last <= step or e.attributes["from_lane"].startswith(":")

    changes = [e for e in switches if current <= e.attributes["change_step"] < last and not undecidable(e)]
    if not changes and (any(undecidable(e) for e in switches) or len(switches) < len(everything)):
        return  # only switches whose showing is undecidable (SETTLE_STEPS, SWERVE_STEPS, junction lanes): not scored
    predicted = [lab for lab in mine if lab.key == "changing_lanes"]
    scores.add("changing_lanes", bool(changes), bool(predicted))
    for side in ("left", "right"):
        truth_side = [e for e in changes if e.attributes["direction"] == side]
        pred_side = [lab for lab in predicted if _direction(lab, scenario, agent) == side]
        overlap = any(lab.start < e.end and e.start < lab.end for lab in pred_side for e in truth_side)
        scores.add(f"changing_lanes_{side}", bool(truth_side), bool(pred_side) and (overlap or not truth_side))


def score_single(scenario: Scenario, labels: tuple[AgentLabel, ...], config: HeuristicConfig, scores: Scores) -> None:
    """Add one window's per-agent comparisons to `scores`."""
    current = scenario.current_index
    ids = scenario.agents.ids
    by_agent: dict[int, list[AgentLabel]] = defaultdict(list)
    for lab in labels:
        by_agent[lab.track_id].append(lab)
    events: dict[int, list] = defaultdict(list)
    for e in scenario.events:
        events[e.track_id].append(e)
    fraction = scenario.agents.valid[:, current:].mean(axis=1)
    for agent, tid in enumerate(ids.tolist()):
        if scenario.agents.types[agent] != AgentType.VEHICLE:
            continue
        if not scenario.agents.valid[agent, current] or fraction[agent] < config.min_future_fraction:
            continue
        valid = scenario.agents.valid[agent, current:]
        if not valid.all():
            continue  # SUMO speed is needed at every future step
        scores.agents += 1
        mine = by_agent.get(tid, [])
        keys = {lab.key for lab in mine}
        vel = scenario.agents.states[agent, current:, StateField.VX : StateField.VY + 1]
        for key, truth in _speed_truth(np.hypot(vel[:, 0], vel[:, 1]), config).items():
            scores.add(key, truth, key in keys)

        _score_lane_changes(scenario, agent, events.get(tid, []), mine, scores)

        passes = [e for e in events.get(tid, []) if e.kind == "junction_pass" and e.attributes["intersection"]]
        crossing = any(min(e.end, scenario.num_steps) - max(e.start, current) >= 5 for e in passes)
        scores.add("crossing_intersection", crossing, "crossing_intersection" in keys)
        future = [e for e in passes if e.end > current]
        whole = len(future) == 1 and future[0].start >= current and not future[0].attributes.get("clipped_end")
        if whole and not future[0].attributes["roundabout"]:
            direction = future[0].attributes["direction"]
            if direction in ("s", "l", "r"):
                scores.add("turning_left", direction == "l", "turning_left" in keys)
                scores.add("turning_right", direction == "r", "turning_right" in keys)
                scores.add("going_straight", direction == "s", "going_straight" in keys)

        _score_pull_over(scenario, events.get(tid, []), keys, scores)


def _score_pull_over(scenario: Scenario, events: list, keys: set[str], scores: Scores) -> None:
    """`pulling_over` against the drivers' executed pull-over decisions (`langtraj.synth.intents`) whose
    stop begins in the future at least `SETTLE_STEPS` before the window's end; an agent whose pull-over stop
    began before the current step is not scored (its sideways move may still come after it)."""
    pulls = [e for e in events if e.kind == "decision" and e.attributes.get("decision") == "pull_over"]
    pulls = [e for e in pulls if e.attributes.get("executed")]
    if any(e.attributes["stopped_step"] < scenario.current_index for e in pulls):
        return
    truth = any(e.attributes["stopped_step"] < scenario.num_steps - SETTLE_STEPS for e in pulls)
    if pulls and not truth:
        return  # the stop begins in the last 2 s: not yet visible
    scores.add("pulling_over", truth, "pulling_over" in keys)


def run(corpus: Path) -> dict:
    config = HeuristicConfig()
    scores = Scores()
    interactions: dict[str, TypeCounts] = {}
    windows = 0
    began = time.perf_counter()
    label_seconds = detect_seconds = 0.0
    manifest = json.loads((corpus / "manifest.json").read_text())
    for path in [corpus / shard["file"] for shard in manifest["shards"] if shard["windows"]]:
        for scenario in read_scenarios(path):
            windows += 1
            t0 = time.perf_counter()
            index = MapIndex.build(scenario.road_map)
            labels, _ = label_agents(scenario, config, index)
            t1 = time.perf_counter()
            predicted = detect_interactions(scenario, labels, map_index=index)
            detect_seconds += time.perf_counter() - t1
            predicted = [lab for lab in predicted if not lab.subtype.added]  # SUMO's events give none of these
            label_seconds += t1 - t0
            interactions = add_counts(interactions, match_interactions(predicted, ground_truth_interactions(scenario)))
            score_single(scenario, labels, config, scores)
    return {
        "windows": windows,
        "vehicles_scored": scores.agents,
        "seconds": round(time.perf_counter() - began, 1),
        "label_ms_per_window": round(1000 * label_seconds / max(windows, 1), 1),
        "detect_ms_per_window": round(1000 * detect_seconds / max(windows, 1), 1),
        "single": {k: _row(c) for k, c in sorted(scores.single.items())},
        "interactions": {k: _row(c) for k, c in interactions.items()},
        "interaction_macro_f1": macro_f1(interactions),
    }


def _row(c: TypeCounts) -> dict:
    return {"tp": c.tp, "fp": c.fp, "fn": c.fn, "precision": c.precision, "recall": c.recall, "f1": c.f1}


def _print(result: dict) -> None:
    print(f"{result['windows']} windows, {result['vehicles_scored']} vehicles scored, {result['seconds']} s")
    print(f"labeling {result['label_ms_per_window']} ms/window, detector {result['detect_ms_per_window']} ms/window")
    print(f"\n{'single-agent label':26s}{'TP':>7s}{'FP':>7s}{'FN':>7s}{'prec':>8s}{'recall':>8s}{'F1':>8s}")
    for key, s in result["single"].items():
        print(f"{key:26s}{s['tp']:7d}{s['fp']:7d}{s['fn']:7d}{s['precision']:8.3f}{s['recall']:8.3f}{s['f1']:8.3f}")
    print(f"\n{'interaction type':26s}{'TP':>7s}{'FP':>7s}{'FN':>7s}{'prec':>8s}{'recall':>8s}{'F1':>8s}")
    for kind, s in result["interactions"].items():
        print(f"{kind:26s}{s['tp']:7d}{s['fp']:7d}{s['fn']:7d}{s['precision']:8.3f}{s['recall']:8.3f}{s['f1']:8.3f}")
    print(f"macro-F1 over types present in ground truth: {result['interaction_macro_f1']:.3f}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--corpus", type=Path, help="a `langtraj synth` output folder (default: make one)")
    parser.add_argument("--windows", type=int, default=200)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", type=Path, help="also write the figures here")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        corpus = args.corpus
        if corpus is None:
            corpus = Path(tmp) / "synth"
            config = FactoryConfig(
                kinds=kind_names(), windows=args.windows, seed=args.seed, out=corpus, workers=args.workers
            )
            run_factory(config, progress=False)
        result = run(corpus)
    _print(result)
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
