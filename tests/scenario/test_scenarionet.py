"""ScenarioNet pickles: safe loading, mapping onto our Scenario, writing, and round trips on the real
Waymo- and nuScenes-derived files."""

from __future__ import annotations

import functools
import math
import os
import pickle
import subprocess
from collections import OrderedDict, defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from langtraj.errors import InputError, ScenarioValidationError
from langtraj.scenario import AgentType, MapFeatureType, Scenario, TrafficLightState
from langtraj.scenario.compare import scenario_differences
from langtraj.scenario.io.base import detect_format
from langtraj.scenario.io.scenarionet import (
    ScenarioNetFormat,
    load_pickle,
    looks_like_scenarionet,
    scenario_from_dict,
    scenario_to_dict,
)
from langtraj.scenario.io.tfrecord import masked_crc32c

T = 12
WHERE = "mini.pkl"


# ---------------------------------------------------------------------------- small scenes


def _track(x0: float, kind: str = "VEHICLE") -> dict[str, Any]:
    t = np.arange(T, dtype=np.float32)
    return {
        "type": kind,
        "state": {
            "position": np.stack([x0 + t, np.full(T, 2.0), np.full(T, 0.5)], axis=1).astype(np.float32),
            "heading": np.full(T, 0.25, np.float32),
            "velocity": np.tile(np.float32([10.0, -1.0]), (T, 1)),
            "length": np.full(T, 4.5, np.float32),
            "width": np.full(T, 2.0, np.float32),
            "height": np.full(T, 1.5, np.float32),
            "valid": np.arange(T) >= 2,
        },
        "metadata": {"type": kind, "object_id": "?", "track_length": T},
    }


def _boundary(kind: str, feature: str) -> dict[str, str]:
    return {
        "lane_start_index": "0",
        "lane_end_index": "2",
        "boundary_type": kind,
        "boundary_feature_id": feature,
    }


def minimal_dict(tk: dict[str, str] | None = None, mk: dict[str, str] | None = None) -> dict[str, Any]:
    """A small valid ScenarioNet dict: two tracks, two lanes, a road line, a stop sign, a crosswalk and
    a traffic light. `tk` / `mk` rename track / map keys (references follow)."""
    tk = {"a": "5", "b": "7", **(tk or {})}
    mk = {"l1": "100", "l2": "101", "line": "200", "stop": "300", "walk": "400", **(mk or {})}

    def ref(name: str) -> int | str:  # ScenarioNet writes plain id lists as ints when it can
        return int(mk[name]) if mk[name].isdigit() else mk[name]

    lane = np.float32([[0, 0, 0], [10, 0, 0], [20, 0, 0]])
    neighbor = {
        "feature_id": mk["l2"],
        "self_start_index": "0",
        "self_end_index": "2",
        "neighbor_start_index": "0",
        "neighbor_end_index": "1",
        "boundaries": [_boundary("ROAD_LINE_BROKEN_SINGLE_WHITE", mk["line"])],
    }
    return {
        "id": "mini",
        "version": "test-version",
        "length": T,
        "tracks": {tk["a"]: _track(0.0), tk["b"]: _track(5.0, "PEDESTRIAN")},
        "dynamic_map_states": {
            mk["l1"]: {
                "type": "TRAFFIC_LIGHT",
                "state": {"object_state": [None, None] + ["LANE_STATE_GO"] * (T - 3) + ["LANE_STATE_STOP"]},
                "lane": ref("l1"),
                "stop_point": np.float32([20, 0, 0]),
                "metadata": {"type": "TRAFFIC_LIGHT"},
            }
        },
        "map_features": {
            mk["l1"]: {
                "type": "LANE_SURFACE_STREET",
                "polyline": lane,
                "speed_limit_mph": 25.0,
                "interpolating": True,
                "entry_lanes": [],
                "exit_lanes": [ref("l2")],
                "left_boundaries": [_boundary("UNKNOWN", mk["line"])],
                "right_boundaries": [],
                "left_neighbor": [neighbor],
                "right_neighbor": [],
            },
            mk["l2"]: {
                "type": "LANE_SURFACE_STREET",
                "polyline": lane + [0, 3.5, 0],
                "entry_lanes": [ref("l1")],
            },
            mk["line"]: {"type": "ROAD_LINE_BROKEN_SINGLE_WHITE", "polyline": (lane + [0, 1.75, 0])[:, :2]},
            mk["stop"]: {"type": "STOP_SIGN", "lane": [ref("l1")], "position": np.float32([18, -1, 0])},
            mk["walk"]: {"type": "CROSSWALK", "polygon": [[5, -2, 0], [7, -2, 0], [7, 5, 0], [5, 5, 0]]},
        },
        "metadata": {
            "ts": np.arange(T, dtype=np.float32) * np.float32(0.1),
            "sdc_id": tk["a"],
            "current_time_index": 10,
            "tracks_to_predict": {tk["b"]: {"track_index": 1, "track_id": tk["b"], "difficulty": 2}},
            "objects_of_interest": [tk["b"]],
            "dataset": "test",
            "coordinate": "waymo",
            "metadrive_processed": False,
            "number_summary": {"object_types": {"VEHICLE", "PEDESTRIAN"}},
        },
    }


def test_minimal_scene_maps_every_field() -> None:
    s = scenario_from_dict(minimal_dict(), where=WHERE)
    assert s.scenario_id == "mini" and s.source_format == "scenarionet"
    assert s.agents.ids.tolist() == [5, 7]
    assert s.agents.types.tolist() == [AgentType.VEHICLE, AgentType.PEDESTRIAN]
    np.testing.assert_array_equal(s.agents.states[1, 3], np.float32([8, 2, 0.5, 0.25, 10, -1, 4.5, 2, 1.5]))
    assert s.agents.valid[:, :2].sum() == 0 and s.agents.valid[:, 2:].all()
    assert (s.sdc_index, s.current_index) == (0, 10)
    assert s.agents.tracks_to_predict.tolist() == [1] and s.agents.prediction_difficulty.tolist() == [2]
    assert s.agents.objects_of_interest.tolist() == [1]
    np.testing.assert_array_equal(s.timestamps, np.arange(T, dtype=np.float32) * np.float32(0.1))

    by_id = s.road_map.by_id
    assert [f.id for f in s.road_map] == [100, 101, 200, 300, 400]
    lane = by_id[100]
    assert lane.type is MapFeatureType.LANE_SURFACE_STREET and lane.points.shape == (3, 3)
    assert lane.exit_lanes == (101,) and lane.entry_lanes == () and by_id[101].entry_lanes == (100,)
    assert lane.speed_limit_mph == 25.0 and lane.interpolating and math.isnan(by_id[101].speed_limit_mph)
    (left,) = lane.left_boundaries
    assert (left.boundary_feature_id, left.boundary_type) == (200, MapFeatureType.ROAD_LINE_UNKNOWN)
    (neighbor,) = lane.left_neighbors
    assert (neighbor.feature_id, neighbor.neighbor_end_index) == (101, 1)
    assert neighbor.boundaries[0].boundary_type is MapFeatureType.ROAD_LINE_BROKEN_SINGLE_WHITE
    np.testing.assert_array_equal(by_id[200].points[:, 2], 0.0)  # 2-D polyline gets z = 0
    assert by_id[300].controlled_lanes == (100,) and by_id[300].points.tolist() == [[18, -1, 0]]
    assert by_id[400].type is MapFeatureType.CROSSWALK and len(by_id[400].points) == 4

    lights = s.traffic_lights
    assert lights.lane_ids.tolist() == [100] and lights.stop_points.tolist() == [[20, 0, 0]]
    assert lights.valid[:, 0].tolist() == [False, False] + [True] * (T - 2)
    assert lights.states[2, 0] == TrafficLightState.GO and lights.states[-1, 0] == TrafficLightState.STOP

    sn = s.metadata["scenarionet"]
    assert sn["version"] == "test-version"
    assert sn["source_metadata"] == {"dataset": "test", "coordinate": "waymo"}
    assert not {"track_keys", "map_keys", "track_types", "map_types", "dropped_references"} & set(sn)


def test_nuscenes_style_columns_and_missing_metadata() -> None:
    d = minimal_dict()
    for track in d["tracks"].values():
        state = track["state"]
        state["position"] = state["position"][:, :2].astype(np.float64)
        state["length"] = state["length"][:, None].astype(np.float64)
        state["valid"] = state["valid"].astype(np.float64)
    del d["metadata"]["current_time_index"], d["metadata"]["ts"], d["metadata"]["sdc_id"]
    d["map_features"]["101"]["speed_limit_kmh"] = 100
    s = scenario_from_dict(d, where=WHERE)
    assert s.agents.states[:, :, 2].max() == 0.0 and s.agents.states[0, 0, 6] == np.float32(4.5)
    assert s.agents.valid[:, 2:].all() and not s.agents.valid[:, :2].any()
    assert s.current_index == 10 and s.sdc_index == -1
    np.testing.assert_allclose(s.timestamps, np.arange(T) * 0.1)
    assert s.road_map.by_id[101].speed_limit_mph == pytest.approx(62.137, abs=1e-3)


def test_string_keys_are_numbered_and_restored() -> None:
    tk = {"a": "ego", "b": "c0ffee"}
    mk = {"l1": "lane-a", "l2": "lane-b", "line": "boundary_0", "stop": "s", "walk": "w"}
    d = minimal_dict(tk, mk)
    d["tracks"]["c0ffee"]["type"] = "TRAFFIC_CONE"
    s = scenario_from_dict(d, where=WHERE)
    assert s.agents.ids.tolist() == [0, 1] and s.agents.types.tolist() == [AgentType.VEHICLE, AgentType.OTHER]
    assert (s.sdc_index, s.agents.objects_of_interest.tolist()) == (0, [1])
    assert [f.id for f in s.road_map] == [0, 1, 2, 3, 4]
    lane = s.road_map.by_id[0]
    assert lane.exit_lanes == (1,) and lane.left_neighbors[0].feature_id == 1
    assert lane.left_boundaries[0].boundary_feature_id == 2 and s.road_map.by_id[3].controlled_lanes == (0,)
    assert s.traffic_lights.lane_ids.tolist() == [0]
    sn = s.metadata["scenarionet"]
    assert sn["track_keys"] == ["ego", "c0ffee"] and sn["track_types"] == ["VEHICLE", "TRAFFIC_CONE"]
    assert sn["map_keys"] == list(mk.values())

    out = scenario_to_dict(s)
    assert list(out["tracks"]) == ["ego", "c0ffee"] and out["tracks"]["c0ffee"]["type"] == "TRAFFIC_CONE"
    assert list(out["map_features"]) == list(mk.values()) and list(out["dynamic_map_states"]) == ["lane-a"]
    written_lane = out["map_features"]["lane-a"]
    assert written_lane["exit_lanes"] == ["lane-b"] and written_lane["left_neighbor"][0]["feature_id"] == "lane-b"
    assert written_lane["left_boundaries"][0] == _boundary("UNKNOWN", "boundary_0")
    meta = out["metadata"]
    assert (meta["sdc_id"], meta["objects_of_interest"], list(meta["tracks_to_predict"])) == (
        "ego",
        ["c0ffee"],
        ["c0ffee"],
    )
    assert scenario_differences(s, scenario_from_dict(out, where=WHERE)) == []


def test_numeric_keys_write_ids_like_scenarionet() -> None:
    out = scenario_to_dict(scenario_from_dict(minimal_dict(), where=WHERE))
    assert list(out["tracks"]) == ["5", "7"] and out["metadata"]["sdc_id"] == "5"
    lane = out["map_features"]["100"]
    assert lane["exit_lanes"] == [101] and out["map_features"]["300"]["lane"] == [100]
    assert lane["left_neighbor"][0]["feature_id"] == "101" and out["dynamic_map_states"]["100"]["lane"] == 100
    assert out["dynamic_map_states"]["100"]["state"]["object_state"][:3] == [None, None, "LANE_STATE_GO"]
    assert lane["speed_limit_kmh"] == pytest.approx(40.234, abs=1e-3)
    for key in ("id", "version", "length", "tracks", "dynamic_map_states", "map_features", "metadata"):
        assert key in out
    metadata_keys = {"ts", "sdc_id", "current_time_index", "sdc_track_index", "objects_of_interest"}
    metadata_keys |= {"tracks_to_predict", "dataset", "scenario_id", "coordinate", "metadrive_processed"}
    assert metadata_keys | {"number_summary"} <= set(out["metadata"])


def test_unknown_references_are_dropped_and_counted() -> None:
    d = minimal_dict(mk={"l1": "lane-a", "l2": "lane-b"})
    d["map_features"]["lane-a"]["exit_lanes"] = ["lane-b", "nowhere"]
    d["map_features"]["lane-a"]["left_neighbor"][0]["feature_id"] = "gone"
    d["dynamic_map_states"]["lane-a"]["lane"] = "missing"
    s = scenario_from_dict(d, where=WHERE)
    lane = s.road_map.by_id[0]
    assert lane.exit_lanes == (1,) and lane.left_neighbors == () and s.traffic_lights.num_lanes == 0
    assert s.metadata["scenarionet"]["dropped_references"] == 3


def test_numeric_dangling_reference_keeps_its_id() -> None:
    d = minimal_dict()
    d["map_features"]["100"]["exit_lanes"] = [101, 999]
    s = scenario_from_dict(d, where=WHERE)
    assert s.road_map.by_id[100].exit_lanes == (101, 999)
    assert "dropped_references" not in s.metadata["scenarionet"]


def test_metadrive_type_aliases() -> None:
    d = minimal_dict()
    d["map_features"]["200"]["type"] = "UNKNOWN_LINE"
    d["map_features"]["101"]["type"] = "LANE_SURFACE_UNSTRUCTURE"
    s = scenario_from_dict(d, where=WHERE)
    assert s.road_map.by_id[200].type is MapFeatureType.ROAD_LINE_UNKNOWN
    assert s.road_map.by_id[101].type is MapFeatureType.LANE_SURFACE_STREET
    out = scenario_to_dict(s)
    assert out["map_features"]["101"]["type"] == "LANE_SURFACE_UNSTRUCTURE"
    assert out["map_features"]["200"]["type"] == "UNKNOWN_LINE"


# ---------------------------------------------------------------------------- errors


def test_unknown_map_type_names_feature_and_field() -> None:
    d = minimal_dict()
    d["map_features"]["200"]["type"] = "ROAD_LINE_PURPLE"
    with pytest.raises(InputError, match=r"mini\.pkl: map feature '200'\.type: unknown map feature type"):
        scenario_from_dict(d, where=WHERE)


def test_nan_position_on_valid_step_names_track_and_step() -> None:
    d = minimal_dict(tk={"b": "ped-1"})
    d["tracks"]["ped-1"]["state"]["position"][1, 0] = np.nan  # invalid step: allowed
    scenario_from_dict(d, where=WHERE)
    d["tracks"]["ped-1"]["state"]["position"][3, 1] = np.nan
    with pytest.raises(ScenarioValidationError, match=r"mini\.pkl: track 'ped-1', step 3: non-finite y"):
        scenario_from_dict(d, where=WHERE)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            lambda d: d["metadata"].update(objects_of_interest=["42"]),
            r"metadata\.objects_of_interest: unknown track key '42'",
        ),
        (lambda d: d["metadata"].update(sdc_id="nobody"), r"metadata\.sdc_id: unknown track key 'nobody'"),
        (
            lambda d: d["metadata"]["tracks_to_predict"].update({"3": {}}),
            r"tracks_to_predict: unknown track key '3'",
        ),
        (lambda d: d["tracks"]["7"]["state"].pop("heading"), r"track '7': missing state field 'heading'"),
        (
            lambda d: d["tracks"]["7"]["state"].update(velocity=np.zeros((T, 4))),
            r"track '7'\.velocity: expected shape",
        ),
        (lambda d: d["tracks"]["5"].update(state=None), r"track '5'\.state: expected a dict"),
        (lambda d: d["metadata"].update(ts=np.zeros(3)), r"metadata\.ts: 3 timestamps for 12 steps"),
        (
            lambda d: d["map_features"]["100"]["left_neighbor"][0].update(self_start_index="x"),
            r"left_neighbor\[0\]\.self_start_index",
        ),
        (
            lambda d: d["map_features"]["100"]["left_boundaries"][0].update(boundary_type="PINK"),
            r"left_boundaries\[0\]\.boundary_type",
        ),
        (
            lambda d: d["map_features"]["400"].update(polygon=[[0, 0, np.inf]]),
            r"map feature '400'.*non-finite",
        ),
        (lambda d: d["map_features"]["300"].pop("position"), r"map feature '300': missing 'position'"),
        (
            lambda d: d["dynamic_map_states"]["100"]["state"]["object_state"].__setitem__(4, "BLUE"),
            r"object_state\[4\]: unknown traffic light state",
        ),
        (lambda d: d.pop("tracks"), r"not a ScenarioNet scenario \(missing key 'tracks'\)"),
    ],
)
def test_bad_fields_name_file_and_place(edit, message: str) -> None:
    d = minimal_dict()
    edit(d)
    with pytest.raises(InputError, match=message) as info:
        scenario_from_dict(d, where=WHERE)
    assert str(info.value).startswith(WHERE)


# ---------------------------------------------------------------------------- files and safety


def _dump(path: Path, obj: Any, protocol: int = 4) -> Path:
    path.write_bytes(pickle.dumps(obj, protocol=protocol))
    return path


def _read(path: Path) -> Scenario:
    (scenario,) = ScenarioNetFormat().read(path)
    return scenario


class _Reduce:
    """Pickles as a call of `func(*args)`: what a malicious file would contain."""

    def __init__(self, func: Any, *args: Any):
        self.func, self.args = func, args

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        return self.func, self.args


@pytest.mark.parametrize("protocol", [2, 4, 5])
@pytest.mark.parametrize(
    ("make", "refused"),
    [
        (lambda marker: _Reduce(os.system, f"echo pwned > {marker}"), "system"),
        (lambda marker: _Reduce(eval, f"open({str(marker)!r}, 'w').write('pwned')"), "builtins.eval"),
        (
            lambda marker: _Reduce(subprocess.Popen, ["sh", "-c", f"echo pwned > {marker}"]),
            "subprocess.Popen",
        ),
    ],
)
def test_malicious_pickles_are_refused_without_running(tmp_path: Path, make, refused: str, protocol: int) -> None:
    marker = tmp_path / "pwned"
    d = minimal_dict()
    d["metadata"]["payload"] = make(marker)  # hidden among ordinary arrays
    path = _dump(tmp_path / "evil.pkl", d, protocol)
    with pytest.raises(InputError, match=rf"evil\.pkl: refused to load global .*{refused}") as info:
        _read(path)
    assert str(path) in str(info.value)
    assert not marker.exists()


def test_os_system_global_is_named(tmp_path: Path) -> None:
    marker = tmp_path / "pwned"
    path = tmp_path / "evil.pkl"
    path.write_bytes(b"cos\nsystem\n(S'echo pwned > " + str(marker).encode() + b"'\ntR.")
    with pytest.raises(InputError, match=r"refused to load global os\.system from pickle"):
        load_pickle(path)
    assert not marker.exists()


def _with_containers(d: dict[str, Any]) -> OrderedDict:
    """`d` with the defaultdicts and OrderedDicts of a real ScenarioNet file (Waymo v1.2 conversion):
    the scenario, its metadata and summaries, the track and map dicts and each track and feature."""
    meta = defaultdict(list, d["metadata"])
    meta["tracks_to_predict"] = OrderedDict(d["metadata"]["tracks_to_predict"])
    meta["object_summary"] = defaultdict(dict, {k: {"type": "VEHICLE"} for k in d["tracks"]})
    meta["number_summary"] = defaultdict(int, {"num_objects": 2})
    tracks = defaultdict(dict)
    for key, track in d["tracks"].items():
        tracks[key] = OrderedDict(
            track, state=OrderedDict(track["state"]), metadata=defaultdict(str, track["metadata"])
        )
    features = defaultdict(OrderedDict, {k: OrderedDict(v) for k, v in d["map_features"].items()})
    lights = defaultdict(dict, d["dynamic_map_states"])
    return OrderedDict(d, metadata=meta, tracks=tracks, map_features=features, dynamic_map_states=lights)


@pytest.mark.parametrize("protocol", [2, 3, 4, 5])
def test_defaultdicts_and_ordered_dicts_load_as_plain_dicts(tmp_path: Path, protocol: int) -> None:
    plain = _read(_dump(tmp_path / "plain.pkl", minimal_dict(), protocol))
    path = _dump(tmp_path / "containers.pkl", _with_containers(minimal_dict()), protocol)
    for name in (b"defaultdict", b"OrderedDict"):
        assert name in path.read_bytes()
    loaded = load_pickle(path)
    assert type(loaded) is dict
    assert {type(loaded[k]) for k in ("metadata", "tracks", "map_features", "dynamic_map_states")} == {dict}
    assert {type(v) for v in [*loaded["tracks"].values(), *loaded["map_features"].values()]} == {dict}
    assert type(loaded["tracks"]["5"]["state"]) is dict and type(loaded["metadata"]["tracks_to_predict"]) is dict
    assert list(loaded["map_features"]) == list(minimal_dict()["map_features"])  # file order kept
    scenario = _read(path)
    assert scenario_differences(plain, scenario, compare_metadata=False) == []
    assert scenario.metadata["scenarionet"]["source_metadata"] == plain.metadata["scenarionet"]["source_metadata"]


@pytest.mark.parametrize("protocol", [2, 4, 5])
@pytest.mark.parametrize(
    ("factory", "refused"),
    [
        (os.system, r"refused to load global (os|posix)\.system"),
        (eval, r"refused to load global builtins\.eval"),
        (getattr, r"refused to load global builtins\.getattr"),
        (subprocess.Popen, r"refused to load global subprocess\.Popen"),
        (functools.partial(os.system, "true"), r"refused to load global functools\.partial"),
        (np.ndarray, r"refused collections\.defaultdict with default factory numpy\.ndarray"),
    ],
)
def test_defaultdict_with_a_code_running_factory_is_refused(
    tmp_path: Path, factory: Any, refused: str, protocol: int
) -> None:
    d = minimal_dict()
    d["metadata"] = defaultdict(factory, d["metadata"])
    path = _dump(tmp_path / "evil.pkl", d, protocol)
    with pytest.raises(InputError, match=rf"evil\.pkl: {refused}") as info:
        _read(path)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("protocol", [2, 4, 5])
@pytest.mark.parametrize("func", [list, dict, int, str])
def test_default_factories_cannot_be_called(tmp_path: Path, func: Any, protocol: int) -> None:
    """builtins.list and the like are admitted as defaultdict factories only, not as calls."""
    d = minimal_dict()
    d["metadata"]["payload"] = _Reduce(func, ())
    path = _dump(tmp_path / "call.pkl", d, protocol)
    with pytest.raises(InputError, match=rf"call\.pkl: refused to call builtins\.{func.__name__} from pickle"):
        _read(path)


def test_truncated_and_non_scenario_pickles(tmp_path: Path, toy_scenario: Scenario) -> None:
    data = pickle.dumps(scenario_to_dict(toy_scenario), protocol=4)
    cut = tmp_path / "cut.pkl"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"cut\.pkl: corrupt or truncated pickle"):
        _read(cut)
    with pytest.raises(InputError, match=r"list\.pkl: not a ScenarioNet scenario \(top level is a list"):
        _read(_dump(tmp_path / "list.pkl", [1, 2, 3]))
    with pytest.raises(InputError, match=r"dict\.pkl: not a ScenarioNet scenario \(missing key 'tracks'\)"):
        _read(_dump(tmp_path / "dict.pkl", {"id": "x"}))
    with pytest.raises(InputError, match=r"absent\.pkl: no such file"):
        _read(tmp_path / "absent.pkl")


def test_sniff() -> None:
    for protocol in (2, 3, 4, 5):
        assert looks_like_scenarionet(pickle.dumps(minimal_dict(), protocol=protocol)[:64])
    assert looks_like_scenarionet(pickle.dumps([1, 2], protocol=4))  # read() then names the problem
    assert not looks_like_scenarionet(pickle.dumps({}, protocol=0))
    length = (0x0480).to_bytes(8, "little")  # a TFRecord header that also starts with 0x80 0x04
    assert not looks_like_scenarionet(length + masked_crc32c(length).to_bytes(4, "little") + bytes(52))
    assert not looks_like_scenarionet(b"")


def test_write_read_round_trip_of_a_built_scene(tmp_path: Path, toy_scenario: Scenario) -> None:
    path = tmp_path / "sub" / "toy.pkl"
    assert ScenarioNetFormat().write(path, iter([toy_scenario])) == 1
    assert isinstance(detect_format(path), ScenarioNetFormat)
    back = _read(path)
    assert scenario_differences(toy_scenario, back, compare_metadata=False) == []
    assert back.events == toy_scenario.events
    assert {k: v for k, v in back.metadata.items() if k != "scenarionet"} == dict(toy_scenario.metadata)
    assert [p.name for p in path.parent.iterdir()] == ["toy.pkl"]  # no temporary file left behind
    again = tmp_path / "again.pkl"
    ScenarioNetFormat().write(again, [back])
    assert scenario_differences(back, _read(again)) == []


def test_protocol_2_file_loads(tmp_path: Path, toy_scenario: Scenario) -> None:
    """Protocol 2 rebuilds bytes with _codecs.encode and sets with __builtin__.set."""
    path = _dump(tmp_path / "p2.pkl", scenario_to_dict(toy_scenario), protocol=2)
    assert b"_codecs\nencode" in path.read_bytes() and b"__builtin__\nset" in path.read_bytes()
    assert scenario_differences(toy_scenario, _read(path), compare_metadata=False) == []


@pytest.mark.parametrize("count", [0, 2])
def test_write_needs_exactly_one_scenario(tmp_path: Path, toy_scenario: Scenario, count: int) -> None:
    path = tmp_path / "out.pkl"
    with pytest.raises(InputError, match="exactly one scenario"):
        ScenarioNetFormat().write(path, [toy_scenario] * count)
    assert not path.exists()


# ---------------------------------------------------------------------------- real files

NUSCENES = [f"sd_nuscenes_v1.0-mini_scene-{n}.pkl" for n in ("0061", "0103", "0553", "0655", "0757")]
WAYMO = [f"sd_training.tfrecord-00000-of-01000_{n}.pkl" for n in ("2a1e44d405a6833f", "8a346109094cd5aa")]
AGENTS_AND_STEPS = {
    WAYMO[0]: (211, 91),
    WAYMO[1]: (115, 91),
    NUSCENES[0]: (226, 191),
    NUSCENES[1]: (122, 196),
    NUSCENES[2]: (57, 201),
    NUSCENES[3]: (141, 201),
    NUSCENES[4]: (30, 201),
}


@pytest.mark.real_data
@pytest.mark.parametrize("name", WAYMO)
def test_real_waymo_files(real_data_dir: Path, name: str) -> None:
    s = _read(real_data_dir / name)
    assert (s.num_agents, s.num_steps) == AGENTS_AND_STEPS[name]
    assert s.scenario_id == name.rsplit("_", 1)[1].removesuffix(".pkl")
    assert s.current_index == 10 and s.sdc_index == s.num_agents - 1
    assert s.agents.types[s.sdc_index] == AgentType.VEHICLE and s.agents.valid[s.sdc_index].all()
    assert len(s.agents.tracks_to_predict) > 0 and len(s.agents.objects_of_interest) == 2
    assert s.traffic_lights.num_lanes > 0 and set(s.traffic_lights.lane_ids.tolist()) <= set(s.road_map.by_id)
    assert s.road_map.road_edges and s.road_map.of_type(MapFeatureType.CROSSWALK)
    assert "track_keys" not in s.metadata["scenarionet"] and "map_keys" not in s.metadata["scenarionet"]
    if name == WAYMO[1]:
        assert s.road_map.of_type(MapFeatureType.LANE_BIKE_LANE) and s.road_map.of_type(MapFeatureType.STOP_SIGN)


@pytest.mark.real_data
@pytest.mark.parametrize("name", NUSCENES)
def test_real_nuscenes_files(real_data_dir: Path, name: str) -> None:
    s = _read(real_data_dir / name)
    assert (s.num_agents, s.num_steps) == AGENTS_AND_STEPS[name]
    assert 191 <= s.num_steps <= 201 and s.current_index == 10
    assert s.sdc_index >= 0 and s.metadata["scenarionet"]["track_keys"][s.sdc_index] == "ego"
    assert s.agents.valid[s.sdc_index].all()
    assert s.road_map.lanes and s.road_map.road_lines and not s.road_map.road_edges
    assert any(f.polygon is not None for f in s.road_map.lanes)
    assert s.traffic_lights.num_lanes == 0
    assert s.metadata["scenarionet"]["source_metadata"]["dataset"] == "nuscenes"


@pytest.mark.real_data
@pytest.mark.parametrize("name", WAYMO + NUSCENES)
def test_real_files_round_trip(real_data_dir: Path, tmp_path: Path, name: str) -> None:
    source = real_data_dir / name
    first = _read(source)
    out = tmp_path / name
    ScenarioNetFormat().write(out, [first])
    second = _read(out)
    assert scenario_differences(first, second) == []
    np.testing.assert_array_equal(first.agents.states, second.agents.states)
    original, written = load_pickle(source), load_pickle(out)
    for part in ("tracks", "map_features", "dynamic_map_states"):
        assert list(written[part]) == list(original[part])
    assert [t["type"] for t in written["tracks"].values()] == [t["type"] for t in original["tracks"].values()]
    assert [f["type"] for f in written["map_features"].values()] == [
        f["type"] for f in original["map_features"].values()
    ]
    assert written["metadata"]["sdc_id"] == original["metadata"]["sdc_id"]


@pytest.mark.real_data
def test_real_truncated_file(real_data_dir: Path, tmp_path: Path) -> None:
    data = (real_data_dir / WAYMO[0]).read_bytes()
    cut = tmp_path / "half.pkl"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"half\.pkl: corrupt or truncated pickle"):
        _read(cut)
