"""`langtraj evaluate SCENARIOS ROLLOUTS [--index I] [--config 2025|2024] [--json] [--out FILE]
[--adversary ID --target ID] [--unconditioned NPZ --agents ID,...]`.

WOSAC realism metrics of rollouts (docs/metrics.md). SCENARIOS is a scenario file or a folder of them,
searched recursively. ROLLOUTS is one `.npz` (scored against scenario I of the file, or with a folder
the scenario whose id the rollouts name) or a folder of `<scenario_id>.npz` files (every matching
scenario in SCENARIOS is scored in parallel and the corpus mean is reported too). For one file,
`--adversary` and `--target` add the safety-critical figures, `--unconditioned` and `--agents` the
minADE of prompted agents with and without text (`langtraj.metrics.controllability`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from langtraj.errors import InputError
from langtraj.fileio import atomic_open
from langtraj.metrics.config import BUCKETS, CONFIGS
from langtraj.metrics.controllability import controllability, safety
from langtraj.metrics.corpus import EvalJob, aggregate, evaluate_corpus, pair_jobs, run_job
from langtraj.metrics.wosac import ScenarioMetrics
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.io import expand_scenario_paths, read_scenario, read_scenarios

_RATES = (
    "average_displacement_error",
    "min_average_displacement_error",
    "simulated_collision_rate",
    "simulated_offroad_rate",
    "simulated_traffic_light_violation_rate",
)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("evaluate", help="WOSAC realism metrics of rollouts (.npz) against their scenarios")
    p.add_argument("scenarios", metavar="SCENARIOS", help="scenario file, or a folder searched recursively")
    p.add_argument("rollouts", metavar="ROLLOUTS", help="rollouts .npz, or a folder of <scenario_id>.npz files")
    p.add_argument("--index", type=int, default=0, help="scenario in the file, for a single .npz (default 0)")
    p.add_argument("--config", choices=sorted(CONFIGS), default="2025", help="challenge configuration")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.add_argument("--out", type=Path, help="also write the JSON report to this file (atomically)")
    p.add_argument("--workers", type=int, default=1, help="scenarios scored at once (folder mode)")
    p.add_argument("--executor", default="process", help="process (default) or ray")
    extra = p.add_argument_group("controllability and safety (single .npz only)")
    extra.add_argument("--adversary", type=int, help="track id of the adversary: adds its collision rate with --target")
    extra.add_argument("--target", type=int, help="track id of the target of --adversary")
    extra.add_argument(
        "--unconditioned", type=Path, help="rollouts of the same scene without text: adds minADE with and without"
    )
    extra.add_argument("--agents", type=_ids, help="comma-separated prompted track ids for --unconditioned")
    p.set_defaults(func=run)


def _ids(text: str) -> list[int]:
    try:
        return [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated track ids, got {text!r}") from None


def _extras(args: argparse.Namespace, scenario_file: str, index: int, rollouts_file: Path) -> dict:
    """The controllability / safety blocks asked for on the command line."""
    if (args.adversary is None) != (args.target is None):
        raise InputError("--adversary and --target go together", where="arguments")
    if (args.unconditioned is None) != (args.agents is None):
        raise InputError("--unconditioned and --agents go together", where="arguments")
    if args.adversary is None and args.unconditioned is None:
        return {}
    scenario = read_scenario(scenario_file, index)
    rollouts = Rollouts.load(rollouts_file)
    out = {}
    if args.adversary is not None:
        out["safety"] = safety(scenario, rollouts, args.adversary, args.target).to_dict()
    if args.unconditioned is not None:
        unconditioned = Rollouts.load(args.unconditioned)
        out["controllability"] = controllability(scenario, rollouts, unconditioned, args.agents).to_dict()
    return out


def _single_scenario(args: argparse.Namespace, rollouts_file: Path) -> tuple[str, int]:
    """The scenario file and index a single rollouts file is scored against: SCENARIOS and --index, or
    in a SCENARIOS folder the scenario whose id the rollouts name."""
    folder = Path(args.scenarios)
    if not folder.is_dir():
        return args.scenarios, args.index
    if args.index != 0:
        raise InputError(
            "applies to a scenario file; in a folder the rollouts' scenario_id picks the scene", where="--index"
        )
    scenario_id = Rollouts.load(rollouts_file).scenario_id
    if not scenario_id:
        raise InputError("the rollouts name no scenario_id: give the scenario file, not a folder", path=rollouts_file)
    for file in expand_scenario_paths([folder]):
        for index, scenario in enumerate(read_scenarios(file)):
            if scenario.scenario_id == scenario_id:
                return str(file), index
    raise InputError(f"no scenario {scenario_id!r} in this folder or its subfolders", path=folder)


def _log_following_note(report: dict) -> str | None:
    """The warning a report carries when some rollouts replay the logged future (log replay)."""
    scenarios = report.get("scenarios", [report])
    flagged = [s for s in scenarios if s.get("log_following_agents")]
    if not flagged:
        return None
    agents = sum(s["log_following_agents"] for s in flagged)
    return (
        f"WARNING: {agents} agents in {len(flagged)} of {len(scenarios)} scenarios replay their logged future "
        "(log replay): a baseline, not a valid WOSAC simulation"
    )


def _table(values: dict, title: str) -> str:
    lines = [title, f"  {'metametric':<42}{values['metametric']:.4f}"]
    for bucket, names in BUCKETS.items():
        lines.append(f"  {bucket + '_metrics':<42}{values[bucket + '_metrics']:.4f}")
        lines.extend(f"    {name + '_likelihood':<40}{values[name + '_likelihood']:.4f}" for name in names)
    lines.extend(f"  {name:<42}{values[name]:.4f}" for name in _RATES)
    if "safety" in values:
        sv = values["safety"]
        lines.append(f"  {'adversary-target collision rate':<42}{sv['pair_collision_rate']:.4f}")
        lines.append(f"  {'collision rate (all agents)':<42}{sv['collision_rate']:.4f}")
        if sv["offroad_rate"] is not None:
            lines.append(f"  {'offroad rate (vehicles)':<42}{sv['offroad_rate']:.4f}")
    if "controllability" in values:
        cv = values["controllability"]
        lines.append(f"  {'minADE with text':<42}{cv['min_ade_conditioned']:.4f}")
        lines.append(f"  {'minADE without text':<42}{cv['min_ade_unconditioned']:.4f}")
        if cv["relative_reduction"] is not None:
            lines.append(f"  {'relative reduction':<42}{cv['relative_reduction']:.4f}")
    return "\n".join(lines)


def _finite_or_null(value):
    """The report with NaN (a feature the scene cannot measure) as JSON null."""
    if isinstance(value, dict):
        return {k: _finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite_or_null(v) for v in value]
    return None if isinstance(value, float) and math.isnan(value) else value


def run(args: argparse.Namespace) -> int:
    rollouts = Path(args.rollouts)
    if rollouts.is_dir():
        if args.adversary is not None or args.unconditioned is not None:
            raise InputError("--adversary / --unconditioned need a single rollouts .npz", where="arguments")
        jobs = pair_jobs(expand_scenario_paths([args.scenarios]), rollouts, args.config)
        results = evaluate_corpus(jobs, workers=args.workers, executor=args.executor)
        report = {
            "config": args.config,
            "num_scenarios": len(results),
            **aggregate(results),
            "scenarios": [r.to_dict() for r in results],
        }
        title = f"WOSAC {args.config}, mean over {len(results)} scenarios"
    else:
        scenario_file, index = _single_scenario(args, rollouts)
        result: ScenarioMetrics = run_job(EvalJob(scenario_file, index, str(rollouts), args.config))
        report = {**result.to_dict(), **_extras(args, scenario_file, index, rollouts)}
        title = f"WOSAC {args.config}, scenario {result.scenario_id}"
    note = _log_following_note(report)  # the JSON says it too: `log_following_agents` per scenario
    text = json.dumps(_finite_or_null(report), indent=2, allow_nan=False)
    if args.out:
        with atomic_open(args.out, "w") as fh:
            fh.write(text + "\n")
    if args.json:
        sys.stdout.write(text + "\n")
    else:
        print(_table(report, title))
    if note:
        print(note, file=sys.stderr)
    return 0
