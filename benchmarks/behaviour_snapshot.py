"""A snapshot of what the behaviour vocabulary makes of scenes, to show a refactor changed nothing: the reader's rule
tables, and on every shared real scene and two synthesized shards, every agent's single-agent feasibility and the
pair behaviours of the agents near the ego toward it (default and swept parameters), each target's numbers and path,
and the steering terms each target gives at three replans (docs/benchmarks.md, 'Behaviour modules: before and
after').

    python benchmarks/behaviour_snapshot.py OUT.json [--real-data DIR]
    python benchmarks/behaviour_snapshot.py --compare A.json B.json

`--compare` lists every value of A that B lacks or holds differently (keys B adds, such as a new field of a
reading, are not differences).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import re
import sys
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np

from langtraj.guidance.steering import Steering
from langtraj.interdrive.behaviour import BEHAVIOURS
from langtraj.interdrive.reader import read_clauses

try:  # the rule tables as the registry gathers them; the commit before the behaviour modules had them as constants
    from langtraj.interdrive.reader.rules import tables

    RULES, SUBSUMES, THEN_KINDS = tables()
except ImportError:
    from langtraj.interdrive.reader.rules import RULES, SUBSUMES, THEN_KINDS  # type: ignore[attr-defined,no-redef]
from langtraj.interdrive.targets import behaviour_feasibility, feasibility
from langtraj.roads import MapIndex
from langtraj.scenario.io import read_scenarios
from langtraj.scenario.types import AgentType, StateField
from langtraj.settings import read_yaml

REPO = Path(__file__).resolve().parents[1]
SYNTH = [
    REPO / "configs" / "suites" / "scenes" / n for n in ("synth-arterial.tfrecord.zst", "synth-onramp.tfrecord.zst")
]
PARAMETERS = {
    "cut_in": [{"gap": 5.0}, {"gap": 15.0}],
    "overtake_cut_in": [{"gap": 5.0}],
    "brake_hard": [{"decel": 6.0}],
}
NEAR = 12
"""How many vehicles nearest the ego are asked about pair behaviours toward it."""


def _rules() -> dict[str, list[str]]:
    """Each behaviour's reader patterns, in order."""
    out: dict[str, list[str]] = {}
    for rule in RULES:
        out.setdefault(str(rule.behaviour), []).append(rule.pattern.pattern)
    return out


def _readings() -> dict[str, Any]:
    """Every prompt of the reader's tests and prompt files, as read."""
    texts = set(re.findall(r'"([^"\n]*@[^"\n]*)"', (REPO / "tests" / "interdrive" / "test_reader.py").read_text()))
    for path in sorted((REPO / "tests" / "data").glob("*.yaml")):
        texts |= {p["text"].replace("{agent}", "@12").replace("{other}", "@7") for p in read_yaml(path)["prompts"]}
    return {t: [r.to_json() for r in read_clauses(t)] for t in sorted(texts)}


def _number(value: Any) -> Any:
    if value is None or isinstance(value, (bool, str, int)):
        return value
    if isinstance(value, float):
        return round(value, 6)
    if hasattr(value, "detach"):  # a tensor
        value = value.detach().cpu().numpy()
    if isinstance(value, np.ndarray):
        return hashlib.sha1(np.round(value.astype(np.float64), 5).tobytes()).hexdigest()[:16] + f":{value.shape}"
    if isinstance(value, (tuple, list)):
        return [_number(v) for v in value]
    if hasattr(value, "__dict__"):  # a route: its numbers
        return {k: _number(v) for k, v in sorted(vars(value).items()) if not callable(v)}
    return repr(value)


def _target(target) -> dict[str, Any]:
    return {k: _number(v) for k, v in vars(target).items()}


def _terms(target, other_driven: bool) -> list[list[Any]]:
    slots = {target.track_id: 0}
    if target.other_id is not None and other_driven:
        slots[target.other_id] = 1
    steering = Steering.of(target, (0.0, 0.0, 0.0), slots)
    out = []
    for elapsed in (0, 10, 30):
        for term in steering.terms(elapsed, 80):
            cost = term.cost
            attrs = {k: _number(v) for k, v in sorted(vars(cost).items()) if not k.startswith("_")}
            out.append([elapsed, type(cost).__name__, _number(float(term.weight)), attrs])
    return out


def _verdict(verdict, other_driven: bool = True) -> dict[str, Any]:
    row: dict[str, Any] = {"status": verdict.status, "reason": verdict.reason}
    if verdict.target is not None:
        row["target"] = _target(verdict.target)
        row["terms"] = _terms(verdict.target, other_driven)
        if verdict.target.other_id is not None:
            row["terms_undriven"] = _terms(verdict.target, False)
    return row


def _scene(scenario) -> dict[str, Any]:
    index = MapIndex.build(scenario.road_map)
    c, agents = scenario.current_index, scenario.agents
    out: dict[str, Any] = {}
    valid = np.flatnonzero(agents.valid[:, c])
    for row in valid:
        track = int(agents.ids[row])
        out[f"single {track}"] = {b: _verdict(v) for b, v in behaviour_feasibility(scenario, track, index).items()}
    ego_row = scenario.sdc_index if scenario.sdc_index >= 0 else int(valid[0])
    ego = int(agents.ids[ego_row])
    xy = agents.states[:, c, [StateField.X, StateField.Y]]
    near = [
        int(r)
        for r in valid[np.argsort(np.linalg.norm(xy[valid] - xy[ego_row], axis=1))]
        if r != ego_row and agents.types[r] == AgentType.VEHICLE
    ][:NEAR]
    for row in near:
        track = int(agents.ids[row])
        for behaviour, spec in BEHAVIOURS.items():
            if not spec.is_pair:
                continue
            for params in [{}, *PARAMETERS.get(str(behaviour), [])]:
                verdict = feasibility(
                    scenario,
                    track,
                    behaviour,
                    index,
                    other_id=ego,
                    gap=params.get("gap"),
                    deceleration=params.get("decel"),
                )
                out[f"pair {track} {behaviour} {ego} {params}"] = _verdict(verdict)
    return out


def snapshot(real: Path) -> dict[str, Any]:
    out: dict[str, Any] = {
        "rules": _rules(),
        "readings": _readings(),
        "subsumes": {str(k): sorted(map(str, v)) for k, v in SUBSUMES.items()},
        "then": {str(k): sorted(map(str, v)) for k, v in THEN_KINDS.items()},
        "specs": {str(b): {f.name: str(getattr(s, f.name)) for f in fields(s)} for b, s in BEHAVIOURS.items()},
    }
    files = sorted(p for p in real.iterdir() if p.suffix in (".tfrecord", ".pkl")) if real.is_dir() else []
    for path in [*files, *SYNTH]:
        for k, scenario in enumerate(read_scenarios(path)):
            if k >= 2:
                break
            out[f"{path.name}#{k}"] = _scene(scenario)
            print(f"{path.name}#{k}: done", file=sys.stderr)
    return out


def compare(a: dict[str, Any], b: dict[str, Any], where: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = [f"{where}/{k}: gone" for k in sorted(set(a) - set(b))]  # what the second adds is not a difference
        for k in sorted(set(a) & set(b)):
            out += compare(a[k], b[k], f"{where}/{k}")
        return out
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True)) for d in compare(x, y, f"{where}[{i}]")]
    return [] if a == b else [f"{where}: {str(a)[:200]} != {str(b)[:200]}"]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?")
    parser.add_argument("--real-data", type=Path, default=REPO.parent / "shared" / "data" / "real")
    parser.add_argument("--compare", nargs=2, metavar="JSON")
    args = parser.parse_args()
    if args.compare:
        a, b = (json.loads(Path(p).read_text()) for p in args.compare)
        diffs = compare(a, b)
        print("\n".join(diffs[:60]))
        print(f"{len(diffs)} differences")
        return 1 if diffs else 0
    Path(args.out).write_text(json.dumps(snapshot(args.real_data), indent=0, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
