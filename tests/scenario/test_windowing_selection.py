"""Windowing long scenes into 11 + 80 steps, and agent selection helpers."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scenario_builders import make_scenario

from langtraj.scenario import AgentType, Scenario
from langtraj.scenario.io import read_scenario
from langtraj.scenario.selection import closest_agents, prioritized_agents, tracks_to_predict
from langtraj.scenario.windowing import WindowSpec, cut_window, iter_windows, window_starts


def test_window_starts_default_and_stride() -> None:
    assert window_starts(91) == [0]
    assert window_starts(90) == []
    assert window_starts(201) == [0, 91]
    assert window_starts(201, WindowSpec(stride=20)) == [0, 20, 40, 60, 80, 100]
    assert window_starts(30, WindowSpec(history=5, future=10, stride=5)) == [0, 5, 10, 15]
    with pytest.raises(ValueError, match="stride"):
        WindowSpec(stride=0)


def test_cut_window_layout_and_agent_filtering() -> None:
    scenario = make_scenario(num_agents=4, num_steps=200)
    window = cut_window(scenario, 50)
    assert window.num_steps == 91
    assert window.current_index == 10
    assert window.scenario_id == "toy_w50"
    assert window.metadata["window"] == {"parent_id": "toy", "start": 50}
    np.testing.assert_allclose(window.timestamps[0], 5.0)
    np.testing.assert_array_equal(window.agents.states, scenario.agents.states[:, 50:141])
    early = cut_window(scenario, 0, WindowSpec(history=5, future=10))
    # agent index 2 is invalid for the first 66 steps: dropped from an early short window
    assert 27 not in early.agents.ids.tolist()
    assert early.sdc_index == 0
    (event,) = cut_window(scenario, 0).events
    assert (event.start, event.end) == (20, 45)


def test_window_keeps_prediction_targets_only_if_valid_at_current_step() -> None:
    scenario = make_scenario(num_agents=3, num_steps=120)
    states_valid = scenario.agents.valid.copy()
    states_valid[1, 20:] = False  # track to predict leaves the scene at step 20
    gone = replace(scenario, agents=replace(scenario.agents, valid=states_valid))
    window = cut_window(gone, 25, WindowSpec(history=11, future=80))
    assert window.agents.tracks_to_predict.size == 0
    assert 1 not in window.agents.objects_of_interest.tolist()


def test_iter_windows_on_long_real_scene(real_data_dir) -> None:
    scene = read_scenario(real_data_dir / "sd_nuscenes_v1.0-mini_scene-0553.pkl")
    windows = list(iter_windows(scene, WindowSpec(stride=50)))
    assert len(windows) == len(window_starts(scene.num_steps, WindowSpec(stride=50))) >= 2
    for w in windows:
        assert w.num_steps == 91 and w.current_index == 10
        assert w.agents.valid.any(axis=1)[np.arange(w.num_agents) != w.sdc_index].all()


def test_closest_agents_orders_by_distance(toy_scenario: Scenario) -> None:
    # at step 10 the agents sit at x = -20 + 8a + speed*1.0; agent 2 is invalid until step 30
    order = closest_agents(toy_scenario, (0.0, 0.0))
    assert 2 not in order.tolist()
    xy = toy_scenario.agents.xy[order, 10]
    assert np.all(np.diff(np.linalg.norm(xy, axis=1)) >= 0)
    assert closest_agents(toy_scenario, (0.0, 0.0), k=1).shape == (1,)
    peds = closest_agents(toy_scenario, (0.0, 0.0), types=(AgentType.PEDESTRIAN,))
    assert peds.tolist() == [1]


def test_prioritized_agents_puts_interest_first(toy_scenario: Scenario) -> None:
    order = prioritized_agents(toy_scenario)
    assert order[:2].tolist() == [0, 1]  # objects of interest (SDC is one of them)
    assert set(order.tolist()) == {0, 1, 3}  # agent 2 is not valid at the current step
    assert prioritized_agents(toy_scenario, 2).tolist() == [0, 1]
    assert tracks_to_predict(toy_scenario).tolist() == [1]
