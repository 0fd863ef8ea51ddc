"""`langtraj submit SCENARIOS ROLLOUTS_DIR --metadata META.json --out DIR`: a WOSAC submission.

Pairs every `<scenario_id>.npz` in ROLLOUTS_DIR with its scenario (SCENARIOS is a file, or a folder
searched recursively), checks each against the challenge's rules (the sim agents, 32 rollouts, 80
steps, finite values), and writes the sharded `SimAgentsChallengeSubmission` protos plus the `.tar.gz`
to upload. META.json holds the
`SubmissionMetadata` fields (account_name, unique_method_name, authors, ...). docs/metrics.md
describes submissions.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import fields, replace
from pathlib import Path

from langtraj.errors import InputError
from langtraj.metrics.corpus import pair_jobs
from langtraj.metrics.submission import SubmissionMetadata, validate_scenario_rollouts, write_submission
from langtraj.rollouts.container import Rollouts
from langtraj.scenario.io import expand_scenario_paths, read_scenario


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser("submit", help="write a WOSAC submission (sharded protos + .tar.gz) from rollouts")
    p.add_argument("scenarios", metavar="SCENARIOS", help="scenario file, or a folder searched recursively")
    p.add_argument("rollouts", metavar="ROLLOUTS_DIR", help="folder of <scenario_id>.npz rollouts")
    p.add_argument("--metadata", required=True, type=Path, help="JSON file with the submission metadata")
    p.add_argument("--out", required=True, type=Path, help="folder for the shards and submission.tar.gz")
    p.add_argument("--shard-size", type=int, default=100, help="scenarios per shard (default 100)")
    p.set_defaults(func=run)


def load_metadata(path: Path) -> SubmissionMetadata:
    """`SubmissionMetadata` from a JSON object; unknown or missing keys name themselves in the error."""
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError("no such file", path=path) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"not valid JSON ({exc})", path=path) from None
    if not isinstance(data, dict):
        raise InputError("expected a JSON object of metadata fields", path=path)
    known = {f.name for f in fields(SubmissionMetadata)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InputError(f"unknown fields {', '.join(unknown)}; known: {', '.join(sorted(known))}", path=path)
    try:
        metadata = SubmissionMetadata(**data)
    except TypeError as exc:
        raise InputError(str(exc), path=path) from None
    try:
        metadata.check()
    except InputError as exc:
        raise exc.located(path=path) from None
    return metadata


def run(args: argparse.Namespace) -> int:
    metadata = load_metadata(args.metadata)
    jobs = pair_jobs(expand_scenario_paths([args.scenarios]), args.rollouts)
    checked = []
    for job in jobs:
        scenario = read_scenario(job.scenario_file, job.index)
        try:
            rollouts = Rollouts.load(job.rollouts_file)
            if rollouts.reads_future_log:
                raise InputError(
                    f"{len(rollouts.log_following_ids)} agents replay their logged future (log replay); WOSAC "
                    "forbids reading the future, so these rollouts cannot be submitted",
                    where="log_following_ids",
                )
            rollouts = validate_scenario_rollouts(scenario, rollouts)
        except InputError as exc:
            raise exc.located(path=job.rollouts_file) from None
        checked.append(replace(rollouts, scenario_id=scenario.scenario_id))
    written = write_submission(checked, args.out, metadata, shard_size=args.shard_size)
    print(
        f"{written.num_scenarios} scenarios in {len(written.shards)} shards under {args.out}"
        + (f"; upload {written.package}" if written.package else "")
    )
    return 0
