"""Waymo Open Sim Agents Challenge (WOSAC) submissions: convert `Rollouts` to and from the challenge's
protos, check them against the challenge's rules, and write or read the sharded submission files.

The messages come from `langtraj.metrics.proto.sim_agents_submission_pb2`, a copy of the public schema
with the same message names and field numbers, so the files written here parse with the official
`waymo_open_dataset.protos.sim_agents_submission_pb2` (and files it wrote parse here).

A submission is a set of binary `SimAgentsChallengeSubmission` shards named
`<prefix>.binproto-00000-of-00003`, ..., each with some scenarios' rollouts and the same metadata, and
packaged for upload as a flat `.tar.gz` of the shards (the layout of the official tutorial,
`tutorial/tutorial_sim_agents.ipynb`).

See docs/metrics.md.
"""

from __future__ import annotations

import os
import re
import tarfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field, fields
from itertools import islice
from pathlib import Path

import numpy as np
from google.protobuf.message import DecodeError

from langtraj.errors import InputError
from langtraj.fileio import atomic_path, open_input
from langtraj.metrics.proto import sim_agents_submission_pb2 as pb
from langtraj.rollouts.container import WOSAC_ROLLOUTS, Rollouts
from langtraj.rollouts.validation import check_rollouts
from langtraj.scenario.model import FUTURE_STEPS, Scenario

ScenarioRollouts = pb.ScenarioRollouts
SimAgentsChallengeSubmission = pb.SimAgentsChallengeSubmission

SHARD_PATTERN = re.compile(r".*\.binproto(-\d{5}-of-\d{5})?")
"""File names the challenge server accepts for submission shards (from the official tutorial)."""

DEFAULT_SHARD_SIZE = 100
"""Scenarios per shard: about 250 MB at a typical 60 sim agents, well under protobuf's 2 GiB limit."""

_MAX_MESSAGE_BYTES = 2**31 - 1  # protobuf cannot serialize or parse a message of 2 GiB or more
_INT32 = np.iinfo(np.int32)
_TRAJECTORY_FIELDS = (("center_x", "x"), ("center_y", "y"), ("center_z", "z"), ("heading", "heading"))


# ---------------------------------------------------------------- Rollouts <-> ScenarioRollouts


def rollouts_to_proto(rollouts: Rollouts, *, scenario_id: str | None = None) -> pb.ScenarioRollouts:
    """One `ScenarioRollouts` message for `rollouts`: a `JointScene` per rollout, a trajectory per agent.

    The float32 values are stored as they are (the proto fields are float32 too), so the round trip
    through `proto_to_rollouts` is exact. `scenario_id` overrides the one the rollouts carry (the
    reference `.npz` files carry none); object ids must fit the proto's int32.
    """
    ids = rollouts.object_id
    if len(ids) and (ids.min() < _INT32.min or ids.max() > _INT32.max):
        bad = ids[(ids < _INT32.min) | (ids > _INT32.max)]
        raise InputError(f"object id {int(bad[0])} does not fit the submission's int32", where="object_id")
    msg = pb.ScenarioRollouts(scenario_id=rollouts.scenario_id if scenario_id is None else scenario_id)
    columns = [getattr(rollouts, name) for _, name in _TRAJECTORY_FIELDS]
    id_list = [int(i) for i in ids]
    for r in range(rollouts.num_rollouts):
        scene = msg.joint_scenes.add()
        for a, object_id in enumerate(id_list):
            traj = scene.simulated_trajectories.add(object_id=object_id)
            for (proto_name, _), values in zip(_TRAJECTORY_FIELDS, columns, strict=True):
                getattr(traj, proto_name).extend(values[r, a].tolist())
    return msg


def proto_to_rollouts(msg: pb.ScenarioRollouts) -> Rollouts:
    """The `Rollouts` a `ScenarioRollouts` message holds (also accepts the official message class).

    Agents are ordered as in the first joint scene; the other scenes may list them in any order but
    must hold the same objects. Every trajectory must have the same number of values in each of its
    four fields. Breaking either rule raises InputError naming the joint scene and object. A message
    without joint scenes gives zero rollouts of zero agents.
    """
    scenes = list(msg.joint_scenes)
    if not scenes:
        empty = np.zeros((0, 0, 0), np.float32)
        return Rollouts(np.zeros(0, np.int64), empty, empty, empty, empty, scenario_id=msg.scenario_id)
    first = scenes[0].simulated_trajectories
    object_ids = np.array([t.object_id for t in first], np.int64)
    order = {int(i): a for a, i in enumerate(object_ids)}
    if len(order) != len(object_ids):
        repeated = sorted({int(i) for i in object_ids if (object_ids == i).sum() > 1})
        raise InputError(f"joint scene 0 lists objects {repeated} more than once", where="joint_scenes")
    steps = len(first[0].center_x) if len(first) else 0
    shape = (len(scenes), len(object_ids), steps)
    arrays = {name: np.empty(shape, np.float32) for _, name in _TRAJECTORY_FIELDS}
    for r, scene in enumerate(scenes):
        seen = np.zeros(len(object_ids), bool)
        for traj in scene.simulated_trajectories:
            a = order.get(traj.object_id)
            if a is None:
                raise InputError(
                    f"joint scene {r} has object {traj.object_id}, which joint scene 0 does not", where="joint_scenes"
                )
            if seen[a]:
                raise InputError(f"joint scene {r} lists object {traj.object_id} twice", where="joint_scenes")
            seen[a] = True
            for proto_name, name in _TRAJECTORY_FIELDS:
                values = getattr(traj, proto_name)
                if len(values) != steps:
                    raise InputError(
                        f"joint scene {r}, object {traj.object_id}: {len(values)} {proto_name} values,"
                        f" expected {steps} (as joint scene 0, object {int(object_ids[0])})",
                        where="joint_scenes",
                    )
                arrays[name][r, a] = values
        if not seen.all():
            missing = object_ids[~seen]
            raise InputError(
                f"joint scene {r} lacks objects {[int(i) for i in missing[:8]]}"
                f"{' ...' if len(missing) > 8 else ''} that joint scene 0 has",
                where="joint_scenes",
            )
    return Rollouts(object_ids, scenario_id=msg.scenario_id, **arrays)


# ---------------------------------------------------------------- the challenge's rules


def validate_scenario_rollouts(scenario: Scenario, rollouts: Rollouts | pb.ScenarioRollouts) -> Rollouts:
    """Check rollouts (a `Rollouts` or a `ScenarioRollouts` message) against the challenge's rules for
    `scenario` and return them as `Rollouts`.

    The rules (those of the official `submission_specs.validate_scenario_rollouts`): the scenario id
    is set (messages only; a `Rollouts` without one is taken to be for `scenario`) and matches;
    exactly 32 joint scenes; each holds exactly the sim agents (every track valid at the current step)
    with 80 steps each; and, stricter than the official check, every value is finite. A broken rule
    raises InputError saying what is wrong.
    """
    if not isinstance(rollouts, Rollouts):
        if not rollouts.scenario_id:
            raise InputError("missing scenario id", where="scenario_id")
        if len(rollouts.joint_scenes) != WOSAC_ROLLOUTS:
            raise InputError(
                f"{len(rollouts.joint_scenes)} joint scenes, the challenge requires {WOSAC_ROLLOUTS}",
                where="joint_scenes",
            )
        rollouts = proto_to_rollouts(rollouts)
    check_rollouts(scenario, rollouts, num_rollouts=WOSAC_ROLLOUTS)
    return rollouts


# ---------------------------------------------------------------- metadata

_NUM_PARAMETERS = re.compile(r"\d+(\.\d+)?[KMBT]?")


@dataclass
class SubmissionMetadata:
    """Who submits what: the metadata every shard of a submission carries.

    `account_name` is the e-mail registered at waymo.com/open; `unique_method_name` names the entry on
    the leaderboard (only the latest result per account and name is shown); `num_model_parameters` is
    an estimate such as "200K" or "1.5B". The challenge requires the three `uses_*` disclosures and the
    closed-loop acknowledgement, which defaults to False so that nobody acknowledges it by accident.
    """

    account_name: str
    unique_method_name: str
    authors: list[str]
    affiliation: str
    description: str
    method_link: str
    uses_lidar_data: bool = False
    uses_camera_data: bool = False
    uses_public_model_pretraining: bool = False
    public_model_names: list[str] = field(default_factory=list)
    num_model_parameters: str = ""
    acknowledge_complies_with_closed_loop_requirement: bool = False

    def check(self) -> None:
        """Raise InputError listing every missing or malformed field (empty strings, no authors, no
        parameter count, no closed-loop acknowledgement, pretraining without model names)."""
        problems = []
        for name in ("account_name", "unique_method_name", "affiliation", "description", "method_link"):
            if not str(getattr(self, name)).strip():
                problems.append(f"{name} is empty")
        if self.account_name.strip() and "@" not in self.account_name:
            problems.append(f"account_name {self.account_name!r} is not the e-mail registered at waymo.com/open")
        if not self.authors or not all(str(a).strip() for a in self.authors):
            problems.append("authors is empty or has an empty name")
        if not self.num_model_parameters.strip():
            problems.append("num_model_parameters is empty (give an estimate such as '200K' or '1.5B')")
        elif not _NUM_PARAMETERS.fullmatch(self.num_model_parameters.strip()):
            problems.append(
                f"num_model_parameters {self.num_model_parameters!r} is not a number with an optional"
                " K, M, B or T suffix (e.g. '200K')"
            )
        if self.uses_public_model_pretraining and not self.public_model_names:
            problems.append("uses_public_model_pretraining is set but public_model_names is empty")
        if not self.acknowledge_complies_with_closed_loop_requirement:
            problems.append(
                "acknowledge_complies_with_closed_loop_requirement is not set (the challenge requires a"
                " closed-loop simulation at 10 Hz; set it once the method complies)"
            )
        if problems:
            raise InputError("; ".join(problems), where="submission metadata")

    def to_proto(self) -> pb.SimAgentsChallengeSubmission:
        """A `SimAgentsChallengeSubmission` with this metadata, the submission type set and no rollouts."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        return pb.SimAgentsChallengeSubmission(
            submission_type=pb.SimAgentsChallengeSubmission.SIM_AGENTS_SUBMISSION,
            **{k: list(v) if isinstance(v, list) else v for k, v in values.items()},
        )

    @classmethod
    def from_proto(cls, msg: pb.SimAgentsChallengeSubmission) -> SubmissionMetadata:
        """The metadata a submission shard carries (unchecked)."""
        values = {f.name: getattr(msg, f.name) for f in fields(cls)}
        return cls(**{k: v if isinstance(v, str | bool) else list(v) for k, v in values.items()})


# ---------------------------------------------------------------- writing


@dataclass(frozen=True)
class WrittenSubmission:
    """What `write_submission` wrote: the shard files in order, the `.tar.gz` (if any), the scenario count."""

    shards: list[Path]
    package: Path | None
    num_scenarios: int


def shard_name(prefix: str, index: int, total: int) -> str:
    """`<prefix>.binproto-00001-of-00003`: the shard naming the challenge server expects."""
    return f"{prefix}.binproto-{index:05d}-of-{total:05d}"


def _checked_item(item: Rollouts | pb.ScenarioRollouts, num_rollouts: int | None) -> pb.ScenarioRollouts:
    """The message for one item after the checks that need no scenario: a scenario id, the number of
    joint scenes, consistent agents, 80 steps, finite values."""
    where = f"scenario {item.scenario_id}" if item.scenario_id else "rollouts"
    try:
        rollouts = item if isinstance(item, Rollouts) else proto_to_rollouts(item)
        if not rollouts.scenario_id:
            raise InputError("missing scenario id (set Rollouts.scenario_id or ScenarioRollouts.scenario_id)")
        if num_rollouts is not None and rollouts.num_rollouts != num_rollouts:
            raise InputError(f"{rollouts.num_rollouts} joint scenes, expected {num_rollouts}")
        if rollouts.num_agents == 0:
            raise InputError("no simulated agents")
        if rollouts.num_steps != FUTURE_STEPS:
            raise InputError(f"{rollouts.num_steps} steps per trajectory, expected {FUTURE_STEPS}")
        rollouts.check_finite()
        if isinstance(item, Rollouts):
            return rollouts_to_proto(item)
    except InputError as exc:
        raise exc.located(where=where) from None
    if not isinstance(item, pb.ScenarioRollouts):  # e.g. the official class: same wire format
        return pb.ScenarioRollouts.FromString(item.SerializeToString())
    return item


def write_submission(
    items: Iterable[Rollouts | pb.ScenarioRollouts],
    out_dir: str | Path,
    metadata: SubmissionMetadata,
    *,
    shard_size: int = DEFAULT_SHARD_SIZE,
    prefix: str = "submission",
    package: bool = True,
    num_rollouts: int | None = WOSAC_ROLLOUTS,
) -> WrittenSubmission:
    """Write a submission: `out_dir/<prefix>.binproto-IIIII-of-NNNNN` shards of `shard_size` scenarios,
    each a `SimAgentsChallengeSubmission` with `metadata`, and (with `package`) `out_dir/<prefix>.tar.gz`
    holding the shards at its top level, ready for upload.

    `items` is streamed (one shard in memory at a time); each must carry a scenario id, unique across
    the submission, and pass the scenario-independent rules (`num_rollouts` joint scenes, 80 steps,
    finite values; check each against its scenario with `validate_scenario_rollouts` first). The
    metadata is checked before anything is written. Shards are staged under hidden names and packaged,
    then renamed into place, so a failure leaves a previous submission in `out_dir` as it
    was. After success, older shards with the same prefix but another shard count, and (without
    `package`) an older `<prefix>.tar.gz`, are removed so the folder holds one consistent set.
    """
    metadata.check()
    if shard_size < 1:
        raise InputError(f"shard_size must be at least 1, got {shard_size}", where="shard_size")
    if not prefix or "/" in prefix or prefix.startswith("."):
        raise InputError(f"bad shard prefix {prefix!r}", where="prefix")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    header = metadata.to_proto()
    staged: list[Path] = []
    seen: set[str] = set()
    iterator = iter(items)
    try:
        while chunk := list(islice(iterator, shard_size)):
            shard = pb.SimAgentsChallengeSubmission()
            shard.CopyFrom(header)
            for item in chunk:
                msg = _checked_item(item, num_rollouts)
                if msg.scenario_id in seen:
                    raise InputError("scenario appears twice in the submission", where=f"scenario {msg.scenario_id}")
                seen.add(msg.scenario_id)
                shard.scenario_rollouts.append(msg)
            size = shard.ByteSize()
            if size > _MAX_MESSAGE_BYTES:
                raise InputError(
                    f"shard {len(staged)} would be {size} bytes, over protobuf's 2 GiB limit; lower shard_size",
                    where="shard_size",
                )
            tmp = out_dir / f".{prefix}.binproto-{len(staged):05d}.staged"
            staged.append(tmp)
            tmp.write_bytes(shard.SerializeToString())
        if not staged:
            raise InputError("no scenario rollouts to write", where="items")
        shards = [out_dir / shard_name(prefix, i, len(staged)) for i in range(len(staged))]
        archive = out_dir / f"{prefix}.tar.gz"
        if package:  # packed from the staged files, so a failure here still changes nothing
            with atomic_path(archive) as tmp, tarfile.open(tmp, "w:gz") as tar:
                for staged_path, final in zip(staged, shards, strict=True):
                    tar.add(staged_path, arcname=final.name)
        for tmp, final in zip(staged, shards, strict=True):
            os.replace(tmp, final)
    except BaseException:
        for tmp in staged:
            tmp.unlink(missing_ok=True)
        raise
    keep = {p.name for p in shards}
    own = re.compile(re.escape(prefix) + r"\.binproto-\d{5}-of-\d{5}")
    for old in out_dir.iterdir():
        if own.fullmatch(old.name) and old.name not in keep:
            old.unlink()
    if not package:
        archive.unlink(missing_ok=True)  # a package of an earlier submission would not match these shards
        archive = None
    return WrittenSubmission(shards, archive, len(seen))


# ---------------------------------------------------------------- reading


def _parse_shard(data: bytes, name: str | Path) -> pb.SimAgentsChallengeSubmission:
    msg = pb.SimAgentsChallengeSubmission()
    try:
        msg.ParseFromString(data)
    except DecodeError as exc:
        raise InputError(f"not a readable submission shard, truncated or corrupt ({exc})", path=name) from None
    if msg.submission_type != pb.SimAgentsChallengeSubmission.SIM_AGENTS_SUBMISSION:
        raise InputError(
            f"not a sim agents submission (submission_type {msg.submission_type}, expected"
            f" {pb.SimAgentsChallengeSubmission.SIM_AGENTS_SUBMISSION})",
            path=name,
        )
    return msg


def _shard_sort_key(name: str) -> tuple[str, int]:
    match = re.fullmatch(r"(.*\.binproto)(?:-(\d{5})-of-\d{5})?", name)
    return (match.group(1), int(match.group(2) or 0)) if match else (name, 0)


def _check_shard_set(names: list[str], where: Path) -> None:
    """Refuse a set of numbered shards with a missing index or mixed totals for one prefix."""
    groups: dict[str, list[tuple[int, int]]] = {}
    for name in names:
        match = re.fullmatch(r"(.*\.binproto)-(\d{5})-of-(\d{5})", name)
        if match:
            groups.setdefault(match.group(1), []).append((int(match.group(2)), int(match.group(3))))
    for stem, numbered in groups.items():
        totals = {total for _, total in numbered}
        if len(totals) > 1:
            raise InputError(f"shards of {stem} mix totals {sorted(totals)}", path=where)
        total = totals.pop()
        missing = sorted(set(range(total)) - {i for i, _ in numbered})
        if missing:
            raise InputError(f"{stem} lacks shards {missing[:8]} of {total}", path=where)


def _read_tar(path: Path) -> list[pb.SimAgentsChallengeSubmission]:
    try:
        with tarfile.open(path, "r:*") as tar:
            members = [m for m in tar.getmembers() if m.isfile() and SHARD_PATTERN.fullmatch(Path(m.name).name)]
            members.sort(key=lambda m: _shard_sort_key(Path(m.name).name))
            _check_shard_set([Path(m.name).name for m in members], path)
            shards = []
            for member in members:
                fh = tar.extractfile(member)
                data = fh.read() if fh is not None else b""
                shards.append(_parse_shard(data, f"{path}:{member.name}"))
    except InputError:
        raise
    except (tarfile.TarError, EOFError, OSError, ValueError) as exc:
        raise InputError(f"not a readable submission archive ({exc})", path=path) from None
    if not shards:
        raise InputError("archive holds no .binproto shard", path=path)
    return shards


def read_submission(path: str | Path) -> list[pb.SimAgentsChallengeSubmission]:
    """The shards of a submission, in shard order.

    `path` is one shard file, a folder of shards (files named like `*.binproto` or
    `*.binproto-00000-of-00003`; a numbered set must be complete) or a `.tar`/`.tar.gz` package. A
    missing, truncated or corrupt file, or one that is not a sim agents submission, raises InputError
    naming it.
    """
    path = Path(path)
    if path.is_dir():
        names = [p.name for p in path.iterdir() if p.is_file() and SHARD_PATTERN.fullmatch(p.name)]
        names.sort(key=_shard_sort_key)
        if not names:
            raise InputError("no .binproto shard in this folder", path=path)
        _check_shard_set(names, path)
        return [_read_shard_file(path / name) for name in names]
    if path.is_file() and tarfile.is_tarfile(path):
        return _read_tar(path)
    return [_read_shard_file(path)]


def _read_shard_file(path: Path) -> pb.SimAgentsChallengeSubmission:
    with open_input(path) as fh:
        data = fh.read()
    return _parse_shard(data, path)


def iter_submission_rollouts(path: str | Path) -> Iterator[Rollouts]:
    """The `Rollouts` of every scenario in a submission (see `read_submission` for `path`), in shard
    order; a malformed scenario raises InputError naming the file and scenario."""
    for shard in read_submission(path):
        for msg in shard.scenario_rollouts:
            try:
                yield proto_to_rollouts(msg)
            except InputError as exc:
                raise exc.located(path=path, where=f"scenario {msg.scenario_id}") from None
