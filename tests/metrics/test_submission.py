"""WOSAC submission protos: Rollouts <-> proto, the challenge's rules, metadata, sharded files, and the
wire format pinned against the public schema."""

from __future__ import annotations

import struct
import tarfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from google.protobuf import descriptor, descriptor_pb2, descriptor_pool, message_factory
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.metrics.proto import sim_agents_submission_pb2 as pb
from langtraj.metrics.submission import (
    SubmissionMetadata,
    iter_submission_rollouts,
    proto_to_rollouts,
    read_submission,
    rollouts_to_proto,
    validate_scenario_rollouts,
    write_submission,
)
from langtraj.rollouts import WOSAC_ROLLOUTS, Rollouts, sim_agent_indices
from langtraj.scenario import FUTURE_STEPS, Scenario
from langtraj.scenario.io import read_scenario


def make_rollouts(scenario: Scenario, *, num_rollouts: int = WOSAC_ROLLOUTS, seed: int = 0) -> Rollouts:
    """Random rollouts for the scenario's sim agents, with a few awkward float32 values mixed in."""
    rng = np.random.default_rng(seed)
    ids = scenario.agents.ids[sim_agent_indices(scenario)]
    shape = (num_rollouts, len(ids), FUTURE_STEPS)
    x, y, z, heading = (rng.normal(0, 100, shape).astype(np.float32) for _ in range(4))
    x[0, 0, :4] = [np.float32(1e-45), -0.0, np.finfo(np.float32).max, np.nextafter(np.float32(1), np.float32(2))]
    return Rollouts(ids, x, y, z, heading, scenario_id=scenario.scenario_id)


def assert_same(a: Rollouts, b: Rollouts) -> None:
    assert a.scenario_id == b.scenario_id
    np.testing.assert_array_equal(a.object_id, b.object_id)
    for name in ("x", "y", "z", "heading"):
        got, want = getattr(b, name), getattr(a, name)
        assert got.dtype == np.float32
        assert got.tobytes() == want.tobytes(), name  # bit-exact, -0.0 included


def metadata(**changes) -> SubmissionMetadata:
    meta = SubmissionMetadata(
        account_name="someone@example.com",
        unique_method_name="langtraj-test",
        authors=["A. Author", "B. Author"],
        affiliation="LangTraj",
        description="Test submission",
        method_link="https://example.com/langtraj",
        num_model_parameters="12M",
        acknowledge_complies_with_closed_loop_requirement=True,
    )
    return replace(meta, **changes)


# ---------------------------------------------------------------- conversion


def test_rollouts_proto_bytes_round_trip_is_exact(toy_scenario: Scenario):
    rollouts = make_rollouts(toy_scenario)
    msg = rollouts_to_proto(rollouts)
    assert msg.scenario_id == toy_scenario.scenario_id
    assert len(msg.joint_scenes) == WOSAC_ROLLOUTS
    assert [t.object_id for t in msg.joint_scenes[0].simulated_trajectories] == rollouts.object_id.tolist()
    back = proto_to_rollouts(pb.ScenarioRollouts.FromString(msg.SerializeToString()))
    assert_same(rollouts, back)


def test_scenario_id_override_and_agent_order_per_scene(toy_scenario: Scenario):
    rollouts = make_rollouts(toy_scenario, num_rollouts=3)
    msg = rollouts_to_proto(replace(rollouts, scenario_id=""), scenario_id="other")
    assert msg.scenario_id == "other"
    # Joint scenes other than the first may list the agents in any order.
    trajs = msg.joint_scenes[1].simulated_trajectories
    reordered = list(reversed([pb.SimulatedTrajectory.FromString(t.SerializeToString()) for t in trajs]))
    del trajs[:]
    trajs.extend(reordered)
    back = proto_to_rollouts(msg)
    np.testing.assert_array_equal(back.x, rollouts.x)


def test_inconsistent_joint_scenes_are_refused(toy_scenario: Scenario):
    msg = rollouts_to_proto(make_rollouts(toy_scenario, num_rollouts=3))
    dropped = pb.ScenarioRollouts()
    dropped.CopyFrom(msg)
    del dropped.joint_scenes[2].simulated_trajectories[1]
    with pytest.raises(InputError, match=r"joint scene 2 lacks objects \[17\]"):
        proto_to_rollouts(dropped)
    short = pb.ScenarioRollouts()
    short.CopyFrom(msg)
    traj = short.joint_scenes[1].simulated_trajectories[0]
    del traj.center_y[-1]
    with pytest.raises(InputError, match=r"joint scene 1, object 7: 79 center_y values, expected 80"):
        proto_to_rollouts(short)
    twice = pb.ScenarioRollouts()
    twice.CopyFrom(msg)
    twice.joint_scenes[1].simulated_trajectories[1].object_id = 7
    with pytest.raises(InputError, match="joint scene 1 lists object 7 twice"):
        proto_to_rollouts(twice)


# ---------------------------------------------------------------- the challenge's rules


def test_valid_rollouts_pass_as_rollouts_and_as_proto(toy_scenario: Scenario):
    rollouts = make_rollouts(toy_scenario)
    assert validate_scenario_rollouts(toy_scenario, rollouts) is rollouts
    assert_same(rollouts, validate_scenario_rollouts(toy_scenario, rollouts_to_proto(rollouts)))


def test_wrong_number_of_joint_scenes(toy_scenario: Scenario):
    msg = rollouts_to_proto(make_rollouts(toy_scenario))
    del msg.joint_scenes[-1]
    with pytest.raises(InputError, match="31 joint scenes, the challenge requires 32"):
        validate_scenario_rollouts(toy_scenario, msg)
    with pytest.raises(InputError, match="31 rollouts, expected 32"):
        validate_scenario_rollouts(toy_scenario, proto_to_rollouts(msg))


def test_missing_sim_agent(toy_scenario: Scenario):
    rollouts = make_rollouts(toy_scenario)
    msg = rollouts_to_proto(rollouts)
    for scene in msg.joint_scenes:
        del scene.simulated_trajectories[-1]
    with pytest.raises(InputError, match=r"missing sim agents 37"):
        validate_scenario_rollouts(toy_scenario, msg)


def test_object_that_is_not_a_sim_agent(toy_scenario: Scenario):
    rollouts = make_rollouts(toy_scenario)
    msg = rollouts_to_proto(rollouts)
    for scene in msg.joint_scenes:
        scene.simulated_trajectories[-1].object_id = 27  # track 2: invalid at the current step
    with pytest.raises(InputError, match=r"missing sim agents 37.*not sim agents .* 27"):
        validate_scenario_rollouts(toy_scenario, msg)


def test_79_steps(toy_scenario: Scenario):
    rollouts = make_rollouts(toy_scenario)
    short = Rollouts(rollouts.object_id, *(getattr(rollouts, n)[..., :79] for n in ("x", "y", "z", "heading")))
    with pytest.raises(InputError, match="79 steps per rollout, expected 80"):
        validate_scenario_rollouts(toy_scenario, short)
    with pytest.raises(InputError, match="79 steps per rollout, expected 80"):
        validate_scenario_rollouts(toy_scenario, rollouts_to_proto(short, scenario_id=toy_scenario.scenario_id))


def test_nan(toy_scenario: Scenario):
    rollouts = make_rollouts(toy_scenario)
    rollouts.heading[5, 1, 42] = np.nan
    with pytest.raises(InputError, match=r"heading: non-finite value at rollout 5, object 17, step 42"):
        validate_scenario_rollouts(toy_scenario, rollouts_to_proto(rollouts))


def test_scenario_id_must_be_set_and_match(toy_scenario: Scenario):
    rollouts = make_rollouts(toy_scenario)
    with pytest.raises(InputError, match="missing scenario id"):
        validate_scenario_rollouts(toy_scenario, rollouts_to_proto(rollouts, scenario_id=""))
    with pytest.raises(InputError, match="rollouts are for scenario 'elsewhere', not 'toy'"):
        validate_scenario_rollouts(toy_scenario, rollouts_to_proto(rollouts, scenario_id="elsewhere"))


# ---------------------------------------------------------------- metadata


def test_metadata_check():
    metadata().check()
    metadata(uses_public_model_pretraining=True, public_model_names=["llama-3-8b"]).check()
    with pytest.raises(InputError) as err:
        SubmissionMetadata("", "m", [], "aff", "desc", "link").check()
    text = str(err.value)
    expected = [
        "account_name is empty",
        "authors is empty",
        "num_model_parameters is empty",
        "acknowledge_complies_with_closed_loop_requirement is not set",
    ]
    assert all(part in text for part in expected), text
    assert "unique_method_name" not in text
    with pytest.raises(InputError, match="not the e-mail"):
        metadata(account_name="someone").check()
    with pytest.raises(InputError, match="num_model_parameters '12 million' is not a number"):
        metadata(num_model_parameters="12 million").check()
    with pytest.raises(InputError, match="public_model_names is empty"):
        metadata(uses_public_model_pretraining=True).check()
    with pytest.raises(InputError, match="authors is empty or has an empty name"):
        metadata(authors=["A", " "]).check()


def test_metadata_proto_round_trip():
    meta = metadata(uses_lidar_data=True, uses_public_model_pretraining=True, public_model_names=["m1", "m2"])
    msg = meta.to_proto()
    assert msg.submission_type == pb.SimAgentsChallengeSubmission.SIM_AGENTS_SUBMISSION
    assert SubmissionMetadata.from_proto(pb.SimAgentsChallengeSubmission.FromString(msg.SerializeToString())) == meta


# ---------------------------------------------------------------- files


@pytest.fixture
def five_scenes() -> list[Rollouts]:
    scenes = [make_scenario(num_agents=3 + i, scenario_id=f"scene{i}", seed=i) for i in range(5)]
    return [make_rollouts(s, seed=i) for i, s in enumerate(scenes)]


def test_write_read_round_trip_over_shards(tmp_path: Path, five_scenes: list[Rollouts]):
    items = [five_scenes[0], rollouts_to_proto(five_scenes[1]), *five_scenes[2:]]  # both kinds of item
    written = write_submission(iter(items), tmp_path / "sub", metadata(), shard_size=2)
    names = [p.name for p in written.shards]
    assert names == [f"submission.binproto-0000{i}-of-00003" for i in range(3)]
    assert written.num_scenarios == 5
    assert written.package == tmp_path / "sub" / "submission.tar.gz"
    assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == [*names, "submission.tar.gz"]
    with tarfile.open(written.package) as tar:
        assert tar.getnames() == names
    for source in (tmp_path / "sub", written.package):
        shards = read_submission(source)
        assert [len(s.scenario_rollouts) for s in shards] == [2, 2, 1]
        assert all(SubmissionMetadata.from_proto(s) == metadata() for s in shards)
        back = list(iter_submission_rollouts(source))
        assert len(back) == 5
        for want, got in zip(five_scenes, back, strict=True):
            assert_same(want, got)
    assert [m.scenario_id for m in read_submission(written.shards[2])[0].scenario_rollouts] == ["scene4"]


def test_rewrite_replaces_the_previous_set(tmp_path: Path, five_scenes: list[Rollouts]):
    write_submission(five_scenes, tmp_path, metadata(), shard_size=1)
    assert len(list(tmp_path.glob("submission.binproto-*"))) == 5
    assert (tmp_path / "submission.tar.gz").is_file()
    written = write_submission(five_scenes[:2], tmp_path, metadata(), shard_size=1, package=False)
    assert sorted(tmp_path.iterdir()) == written.shards
    assert [p.name for p in written.shards] == [
        "submission.binproto-00000-of-00002",
        "submission.binproto-00001-of-00002",
    ]


def test_bad_item_leaves_nothing_behind(tmp_path: Path, five_scenes: list[Rollouts]):
    bad = five_scenes[3]
    bad.x[0, 0, 0] = np.inf
    with pytest.raises(InputError, match=r"scenario scene3, x: non-finite value at rollout 0"):
        write_submission(five_scenes, tmp_path, metadata(), shard_size=2)
    assert list(tmp_path.iterdir()) == []


def test_write_refuses_bad_submissions(tmp_path: Path, five_scenes: list[Rollouts]):
    with pytest.raises(InputError, match="scenario scene1: scenario appears twice"):
        write_submission([five_scenes[1], five_scenes[1]], tmp_path, metadata())
    with pytest.raises(InputError, match="missing scenario id"):
        write_submission([replace(five_scenes[0], scenario_id="")], tmp_path, metadata())
    few = Rollouts(five_scenes[0].object_id, *(getattr(five_scenes[0], n)[:4] for n in ("x", "y", "z", "heading")))
    with pytest.raises(InputError, match="4 joint scenes, expected 32"):
        write_submission([replace(few, scenario_id="few")], tmp_path, metadata())
    with pytest.raises(InputError, match="no scenario rollouts"):
        write_submission([], tmp_path, metadata())
    with pytest.raises(InputError, match="submission metadata: account_name is empty"):
        write_submission(five_scenes, tmp_path, metadata(account_name=""))
    assert list(tmp_path.iterdir()) == []


def test_corrupt_or_foreign_files_name_the_file(tmp_path: Path, five_scenes: list[Rollouts]):
    written = write_submission(five_scenes[:1], tmp_path / "ok", metadata(), package=False)
    data = written.shards[0].read_bytes()
    truncated = tmp_path / "truncated.binproto"
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"truncated\.binproto: not a readable submission shard"):
        read_submission(truncated)
    garbage = tmp_path / "garbage.binproto"
    garbage.write_bytes(b"\xff\xff\xff\xff")
    with pytest.raises(InputError, match=r"garbage\.binproto: not a readable submission shard"):
        read_submission(garbage)
    empty = tmp_path / "empty.binproto"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match=r"empty\.binproto: not a sim agents submission"):
        read_submission(empty)
    with pytest.raises(InputError, match=r"absent\.binproto: no such file"):
        read_submission(tmp_path / "absent.binproto")
    (tmp_path / "none").mkdir()
    with pytest.raises(InputError, match=r"none: no .binproto shard in this folder"):
        read_submission(tmp_path / "none")
    gapped = tmp_path / "gapped"
    gapped.mkdir()
    (gapped / "submission.binproto-00001-of-00002").write_bytes(data)
    with pytest.raises(InputError, match=r"gapped: .*lacks shards \[0\] of 2"):
        read_submission(gapped)
    archive = tmp_path / "broken.tar.gz"
    with tarfile.open(archive, "w:gz") as tar:
        tar.add(truncated, arcname="submission.binproto")
    with pytest.raises(InputError, match=r"broken\.tar\.gz:submission\.binproto: not a readable submission shard"):
        read_submission(archive)
    cut = tmp_path / "cut.tar.gz"
    whole = (tmp_path / "whole.tar.gz").with_suffix("")
    with tarfile.open(whole, "w") as tar:
        tar.add(written.shards[0], arcname="submission.binproto")
    cut.write_bytes(whole.read_bytes()[:1000])
    with pytest.raises(InputError, match=r"cut\.tar\.gz: not a readable"):
        read_submission(cut)


# ---------------------------------------------------------------- wire format (the public schema)


def _varint(value: int) -> bytes:
    out = bytearray()
    while True:
        byte, value = value & 0x7F, value >> 7
        out.append(byte | (0x80 if value else 0))
        if not value:
            return bytes(out)


def _field(number: int, wire_type: int, payload: bytes | int) -> bytes:
    tag = _varint(number << 3 | wire_type)
    if wire_type == 0:
        return tag + _varint(payload)
    return tag + _varint(len(payload)) + payload


def _floats(values: list[float]) -> bytes:
    return struct.pack(f"<{len(values)}f", *values)


def test_wire_bytes_match_the_public_schema():
    """Hand-encoded bytes following the public field numbers: floats packed in fields 2-5, object_id a
    varint in field 6; joint scenes in field 2 of ScenarioRollouts; metadata in fields 2-14."""
    traj = pb.SimulatedTrajectory(center_x=[1.0, 2.5], center_y=[-1.0], center_z=[0.0], heading=[0.5], object_id=7)
    traj_bytes = (
        _field(2, 2, _floats([1.0, 2.5]))
        + _field(3, 2, _floats([-1.0]))
        + _field(4, 2, _floats([0.0]))
        + _field(5, 2, _floats([0.5]))
        + _field(6, 0, 7)
    )
    assert traj.SerializeToString() == traj_bytes
    assert traj_bytes[:2] == b"\x12\x08"  # field 2, length-delimited (packed), 8 bytes
    scene_bytes = _field(1, 2, traj_bytes)
    rollouts_bytes = _field(1, 2, b"s1") + _field(2, 2, scene_bytes)
    msg = pb.ScenarioRollouts(scenario_id="s1", joint_scenes=[pb.JointScene(simulated_trajectories=[traj])])
    assert msg.SerializeToString() == rollouts_bytes

    sub = pb.SimAgentsChallengeSubmission(
        scenario_rollouts=[msg],
        submission_type=pb.SimAgentsChallengeSubmission.SIM_AGENTS_SUBMISSION,
        account_name="a@b",
        unique_method_name="m",
        authors=["x", "y"],
        affiliation="f",
        description="d",
        method_link="l",
        uses_lidar_data=True,
        uses_camera_data=True,
        uses_public_model_pretraining=True,
        num_model_parameters="1K",
        public_model_names=["p"],
        acknowledge_complies_with_closed_loop_requirement=True,
    )
    expected = (
        _field(1, 2, rollouts_bytes)
        + _field(2, 0, 1)
        + _field(3, 2, b"a@b")
        + _field(4, 2, b"m")
        + _field(5, 2, b"x")
        + _field(5, 2, b"y")
        + _field(6, 2, b"f")
        + _field(7, 2, b"d")
        + _field(8, 2, b"l")
        + _field(9, 0, 1)
        + _field(10, 0, 1)
        + _field(11, 0, 1)
        + _field(12, 2, b"1K")
        + _field(13, 2, b"p")
        + _field(14, 0, 1)
    )
    assert sub.SerializeToString(deterministic=True) == expected
    assert pb.SimAgentsChallengeSubmission.FromString(expected) == sub


_F = descriptor.FieldDescriptor
PUBLIC_SCHEMA = {  # message: {field: (number, type, repeated)}; from the public sim_agents_submission.proto
    "SimulatedTrajectory": {
        "center_x": (2, _F.TYPE_FLOAT, True),
        "center_y": (3, _F.TYPE_FLOAT, True),
        "center_z": (4, _F.TYPE_FLOAT, True),
        "heading": (5, _F.TYPE_FLOAT, True),
        "object_id": (6, _F.TYPE_INT32, False),
    },
    "JointScene": {"simulated_trajectories": (1, _F.TYPE_MESSAGE, True)},
    "ScenarioRollouts": {"scenario_id": (1, _F.TYPE_STRING, False), "joint_scenes": (2, _F.TYPE_MESSAGE, True)},
    "SimAgentsChallengeSubmission": {
        "scenario_rollouts": (1, _F.TYPE_MESSAGE, True),
        "submission_type": (2, _F.TYPE_ENUM, False),
        "account_name": (3, _F.TYPE_STRING, False),
        "unique_method_name": (4, _F.TYPE_STRING, False),
        "authors": (5, _F.TYPE_STRING, True),
        "affiliation": (6, _F.TYPE_STRING, False),
        "description": (7, _F.TYPE_STRING, False),
        "method_link": (8, _F.TYPE_STRING, False),
        "uses_lidar_data": (9, _F.TYPE_BOOL, False),
        "uses_camera_data": (10, _F.TYPE_BOOL, False),
        "uses_public_model_pretraining": (11, _F.TYPE_BOOL, False),
        "num_model_parameters": (12, _F.TYPE_STRING, False),
        "public_model_names": (13, _F.TYPE_STRING, True),
        "acknowledge_complies_with_closed_loop_requirement": (14, _F.TYPE_BOOL, False),
    },
}


def test_descriptor_matches_the_public_schema():
    file_proto = descriptor_pb2.FileDescriptorProto()
    pb.DESCRIPTOR.CopyToProto(file_proto)
    assert file_proto.syntax in ("", "proto2")
    for message, fields in PUBLIC_SCHEMA.items():
        desc = pb.DESCRIPTOR.message_types_by_name[message]
        got = {f.name: (f.number, f.type, f.is_repeated) for f in desc.fields}
        assert got == fields, message
        # proto2 `optional`: singular fields track presence (the official validator calls HasField("scenario_id")).
        assert all(f.has_presence for f in desc.fields if not f.is_repeated), message
    floats = pb.SimulatedTrajectory.DESCRIPTOR.fields_by_name
    assert all(floats[n].is_packed for n in ("center_x", "center_y", "center_z", "heading"))
    enum = pb.SimAgentsChallengeSubmission.DESCRIPTOR.enum_types_by_name["SubmissionType"]
    assert {v.name: v.number for v in enum.values} == {"UNKNOWN": 0, "SIM_AGENTS_SUBMISSION": 1}


def test_messages_of_another_class_with_the_public_names_interoperate(tmp_path: Path, toy_scenario: Scenario):
    """Our schema loaded under the official package and file name in a separate pool stands in for the
    official `sim_agents_submission_pb2`: its messages are accepted and it parses what we write."""
    file_proto = descriptor_pb2.FileDescriptorProto()
    pb.DESCRIPTOR.CopyToProto(file_proto)
    file_proto.package = "waymo.open_dataset"
    file_proto.name = "waymo_open_dataset/protos/sim_agents_submission.proto"
    for message in file_proto.message_type:
        for fld in message.field:
            if fld.HasField("type_name"):
                fld.type_name = fld.type_name.replace(".langtraj.wosac.", ".waymo.open_dataset.")
    pool = descriptor_pool.DescriptorPool()
    pool.Add(file_proto)
    official = message_factory.GetMessageClass(pool.FindMessageTypeByName("waymo.open_dataset.ScenarioRollouts"))
    official_sub = message_factory.GetMessageClass(
        pool.FindMessageTypeByName("waymo.open_dataset.SimAgentsChallengeSubmission")
    )
    rollouts = make_rollouts(toy_scenario)
    foreign = official.FromString(rollouts_to_proto(rollouts).SerializeToString())
    assert_same(rollouts, validate_scenario_rollouts(toy_scenario, foreign))
    written = write_submission([foreign], tmp_path, metadata(), package=False)
    parsed = official_sub.FromString(written.shards[0].read_bytes())
    assert parsed.unique_method_name == "langtraj-test"
    assert parsed.scenario_rollouts[0].HasField("scenario_id")
    assert_same(rollouts, proto_to_rollouts(parsed.scenario_rollouts[0]))


# ---------------------------------------------------------------- real data


@pytest.mark.real_data
def test_reference_rollouts_validate_and_round_trip(real_data_dir: Path, wosac_reference: Path, tmp_path: Path):
    scenario = read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord")
    rollouts = Rollouts.load(wosac_reference / "rollouts_637f20cafde22ff8_log.npz")
    validate_scenario_rollouts(scenario, rollouts)
    msg = rollouts_to_proto(rollouts, scenario_id=scenario.scenario_id)
    back = validate_scenario_rollouts(scenario, pb.ScenarioRollouts.FromString(msg.SerializeToString()))
    assert_same(replace(rollouts, scenario_id=scenario.scenario_id), back)
    written = write_submission([msg], tmp_path, metadata())
    (again,) = iter_submission_rollouts(written.package)
    assert_same(back, again)
