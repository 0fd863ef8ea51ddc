"""The Scenario data model: dtype coercion, validation errors, selection and slicing."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scenario_builders import make_scenario

from langtraj.errors import ScenarioValidationError
from langtraj.scenario import Agents, MapFeature, MapFeatureType, RoadMap, Scenario, StateField, TrafficLights


def test_arrays_are_coerced_to_contract_dtypes(toy_scenario: Scenario) -> None:
    agents = toy_scenario.agents
    assert agents.ids.dtype == np.int64
    assert agents.types.dtype == np.int8
    assert agents.states.dtype == np.float32
    assert agents.states.shape == (4, 91, len(StateField))
    assert agents.valid.dtype == bool
    assert toy_scenario.timestamps.dtype == np.float64
    assert toy_scenario.traffic_lights.states.dtype == np.int8
    assert all(f.points.dtype == np.float64 and f.points.shape[1] == 3 for f in toy_scenario.road_map)


def test_views_match_state_columns(toy_scenario: Scenario) -> None:
    agents = toy_scenario.agents
    np.testing.assert_array_equal(agents.xy[..., 0], agents.states[..., StateField.X])
    np.testing.assert_allclose(agents.speed[0], 2.0)
    assert agents.index_of(17) == 1
    with pytest.raises(KeyError, match="track id 999"):
        agents.index_of(999)


def test_nan_position_on_valid_step_is_rejected_with_track_and_step() -> None:
    states = np.zeros((2, 5, 9), np.float32)
    states[1, 3, StateField.Y] = np.nan
    with pytest.raises(ScenarioValidationError, match=r"track 8, step 3.*non-finite y"):
        Agents(ids=[7, 8], types=[1, 1], states=states, valid=np.ones((2, 5), bool))


def test_nan_on_invalid_step_is_allowed() -> None:
    states = np.zeros((1, 5, 9), np.float32)
    states[0, 3] = np.nan
    valid = np.ones((1, 5), bool)
    valid[0, 3] = False
    assert Agents(ids=[7], types=[1], states=states, valid=valid).num_agents == 1


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"ids": [1, 1]}, "duplicate track ids"),
        ({"types": [1, 9]}, "unknown agent type 9"),
        ({"valid": np.ones((2, 4), bool)}, "does not match states"),
        ({"tracks_to_predict": [5]}, "index out of range"),
        ({"states": np.zeros((2, 5, 7))}, "expected shape"),
    ],
)
def test_agents_contract_violations(change: dict, message: str) -> None:
    fields = {"ids": [1, 2], "types": [1, 2], "states": np.zeros((2, 5, 9)), "valid": np.ones((2, 5), bool)}
    with pytest.raises(ScenarioValidationError, match=message):
        Agents(**{**fields, **change})


def test_scenario_contract_violations(toy_scenario: Scenario) -> None:
    with pytest.raises(ScenarioValidationError, match="timestamps"):
        replace(toy_scenario, timestamps=np.arange(3.0))
    with pytest.raises(ScenarioValidationError, match="current_index"):
        replace(toy_scenario, current_index=91)
    with pytest.raises(ScenarioValidationError, match="sdc_index"):
        replace(toy_scenario, sdc_index=4)
    with pytest.raises(ScenarioValidationError, match="duplicate map feature id 1"):
        RoadMap((MapFeature(1, MapFeatureType.CROSSWALK, np.zeros((4, 3))),) * 2)
    with pytest.raises(ScenarioValidationError, match="unknown map feature type"):
        MapFeature(1, 99, np.zeros((2, 3)))
    with pytest.raises(ScenarioValidationError, match="traffic_lights"):
        TrafficLights([1, 2], np.zeros((5, 1)), np.zeros((5, 1), bool), np.zeros((2, 3)))


def test_two_dimensional_map_points_get_zero_z() -> None:
    feature = MapFeature(3, MapFeatureType.ROAD_LINE_SOLID_SINGLE_WHITE, [[0.0, 1.0], [2.0, 3.0]])
    np.testing.assert_array_equal(feature.points, [[0, 1, 0], [2, 3, 0]])
    assert MapFeature(4, MapFeatureType.LANE_FREEWAY, np.zeros((2, 3)), speed_limit_mph=10).speed_limit_mps == (
        pytest.approx(4.4704)
    )


def test_select_agents_remaps_indices_and_drops_events(toy_scenario: Scenario) -> None:
    picked = toy_scenario.select_agents([3, 1])
    assert picked.agents.ids.tolist() == [37, 17]
    assert picked.sdc_index == -1  # the SDC (index 0) was dropped
    assert picked.agents.objects_of_interest.tolist() == [1]
    assert picked.agents.tracks_to_predict.tolist() == [1]
    assert [e.track_id for e in picked.events] == [17]
    with_sdc = toy_scenario.select_agents([2, 0])
    assert with_sdc.sdc_index == 1
    assert with_sdc.events == ()  # the event belongs to track 17, not kept


def test_slice_steps_clips_and_shifts_events() -> None:
    scenario = make_scenario(num_agents=3)
    sliced = scenario.slice_steps(30, 60, current_index=5)
    assert sliced.num_steps == 30
    assert sliced.timestamps[0] == pytest.approx(3.0)
    assert sliced.traffic_lights.states.shape == (30, 1)
    (event,) = sliced.events
    assert (event.start, event.end) == (0, 15)
    with pytest.raises(IndexError):
        scenario.slice_steps(80, 100, current_index=0)


def test_a_light_at_a_step_is_its_last_valid_state_up_to_then_never_a_later_one():
    red, green = 4, 6
    states = np.array([[red, 0, 0], [0, green, 0], [0, 0, 0], [green, red, red]], np.int8)  # [T = 4, L = 3]
    valid = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 0], [1, 1, 1]], bool)
    lights = TrafficLights([1, 2, 3], states, valid, np.zeros((3, 3)))
    held, known = lights.held_at(2)  # lane 1 last seen red at 0, lane 2 green at 1, lane 3 not yet
    assert held.tolist() == [red, green, 0] and known.tolist() == [True, True, False]
    held, known = lights.held_at(3)
    assert held.tolist() == [green, red, red] and known.all()
    assert lights.held_at(0)[0].tolist() == [red, 0, 0]
