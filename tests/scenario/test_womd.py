"""WOMD Scenario TFRecords: the real Waymo file, schema compatibility, round trips, bad input."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from google.protobuf.unknown_fields import UnknownFieldSet
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.scenario import MapFeatureType, Scenario
from langtraj.scenario.compare import scenario_differences
from langtraj.scenario.io import read_scenario, read_scenarios, write_scenarios
from langtraj.scenario.io.proto import womd_pb2
from langtraj.scenario.io.tfrecord import iter_records, write_records
from langtraj.scenario.io.womd import scenario_to_proto


def _unknown_field_paths(msg, path: str = "Scenario") -> list[str]:
    found = [path] if len(UnknownFieldSet(msg)) else []
    for desc, value in msg.ListFields():
        if desc.type == desc.TYPE_MESSAGE:
            for child in value if desc.is_repeated else [value]:
                found += _unknown_field_paths(child, f"{path}.{desc.name}")
    return found


@pytest.fixture(scope="module")
def real_womd(real_data_dir: Path) -> Scenario:
    return read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord")


def test_real_scenario_facts(real_womd: Scenario) -> None:
    s = real_womd
    assert s.scenario_id == "637f20cafde22ff8"
    assert (s.num_agents, len(s.road_map), s.num_steps, s.current_index) == (83, 301, 91, 10)
    assert s.source_format == "womd"
    assert s.sdc_id == 2406
    assert s.agents.ids[s.agents.tracks_to_predict].tolist() == [2320, 1676, 1675]
    assert s.agents.prediction_difficulty.tolist() == [1, 1, 2]
    assert s.agents.type_counts() == {"vehicle": 70, "pedestrian": 10, "cyclist": 3, "other": 0}
    assert s.traffic_lights.num_lanes == 12 and s.traffic_lights.valid.all()
    lanes = s.road_map.lanes
    assert len(lanes) == 199
    assert sum(bool(f.entry_lanes or f.exit_lanes) for f in lanes) > 150  # connectivity is kept
    assert any(f.left_neighbors or f.right_neighbors for f in lanes)
    assert len(s.road_map.of_type(MapFeatureType.STOP_SIGN)) == 8
    assert any(f.controlled_lanes for f in s.road_map.of_type(MapFeatureType.STOP_SIGN))
    np.testing.assert_allclose(s.timestamps[[0, 90]], [0.0, 9.0], atol=1e-3)
    sdc_xy = s.agents.xy[s.sdc_index, s.current_index]
    assert np.isfinite(sdc_xy).all() and s.agents.valid[s.sdc_index].all()


def test_schema_parses_the_real_record_without_unknown_fields(real_data_dir: Path) -> None:
    (payload,) = iter_records(real_data_dir / "motion_data_one_scenario.tfrecord")
    msg = womd_pb2.Scenario.FromString(payload)
    assert _unknown_field_paths(msg) == []
    assert msg.SerializeToString() == payload  # every byte is accounted for by the schema


def test_real_round_trip_is_identical(real_womd: Scenario, tmp_path: Path) -> None:
    out = tmp_path / "copy.tfrecord"
    assert write_scenarios(out, [real_womd]) == 1
    assert scenario_differences(real_womd, read_scenario(out)) == []


def test_toy_round_trip_keeps_events_metadata_and_missing_light_steps(tmp_path: Path) -> None:
    scenario = make_scenario()
    valid = scenario.traffic_lights.valid.copy()
    valid[5:9] = False  # the source reported nothing for these steps
    scenario = replace(scenario, traffic_lights=replace(scenario.traffic_lights, valid=valid))
    out = tmp_path / "toy.tfrecord"
    write_scenarios(out, [scenario, replace(scenario, scenario_id="second")])
    first, second = read_scenarios(out)
    assert scenario_differences(scenario, first) == []
    assert second.scenario_id == "second"
    assert first.events[0].attributes == {"direction": "left", "reason": "speedGain"}


def test_read_one_skips_to_index_and_streams(tmp_path: Path) -> None:
    out = tmp_path / "three.tfrecord"
    write_scenarios(out, [make_scenario(scenario_id=f"s{i}") for i in range(3)])
    assert read_scenario(out, 2).scenario_id == "s2"
    with pytest.raises(InputError, match="no scenario at index 3"):
        read_scenario(out, 3)


def test_nan_position_names_file_record_and_track(tmp_path: Path) -> None:
    msg = scenario_to_proto(make_scenario())
    msg.tracks[1].states[40].center_y = float("nan")
    out = tmp_path / "nan.tfrecord"
    write_records(out, [scenario_to_proto(make_scenario()).SerializeToString(), msg.SerializeToString()])
    with pytest.raises(InputError, match=r"nan.tfrecord: record 1, track 17, step 40: non-finite y"):
        list(read_scenarios(out))


def test_garbage_payload_is_reported(tmp_path: Path) -> None:
    out = tmp_path / "garbage.tfrecord"
    write_records(out, [b"\xff\xff\xff\xff not a proto"])
    with pytest.raises(InputError, match=r"garbage.tfrecord: record 0: cannot decode a Scenario proto"):
        read_scenario(out)


def test_record_of_another_proto_is_reported(tmp_path: Path) -> None:
    out = tmp_path / "other.tfrecord"
    write_records(out, [womd_pb2.MapPoint(x=1.0).SerializeToString()])
    with pytest.raises(InputError, match="record 0: record holds no WOMD Scenario"):
        read_scenario(out)


def test_track_with_wrong_number_of_states(tmp_path: Path) -> None:
    msg = scenario_to_proto(make_scenario())
    del msg.tracks[0].states[-1]
    out = tmp_path / "short.tfrecord"
    write_records(out, [msg.SerializeToString()])
    with pytest.raises(InputError, match="track 7: 90 states for 91 timestamps"):
        read_scenario(out)


def test_more_light_steps_than_timestamps_is_reported(tmp_path: Path) -> None:
    msg = scenario_to_proto(make_scenario())
    msg.dynamic_map_states.add()
    out = tmp_path / "lights.tfrecord"
    write_records(out, [msg.SerializeToString()])
    with pytest.raises(InputError, match="dynamic_map_states: 92 dynamic map states for 91 timestamps"):
        read_scenario(out)
