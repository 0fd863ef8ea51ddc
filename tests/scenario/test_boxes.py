"""Boxes checked on read: a vehicle wider than long gets its length and width swapped, with one warning naming the
file; other agents and other scenes are left as they are."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scenario_builders import make_scenario

from langtraj.errors import DataWarning
from langtraj.scenario.boxes import fix_box_sizes
from langtraj.scenario.io import read_scenario, write_scenarios
from langtraj.scenario.types import AgentType, StateField

SIZE = [StateField.LENGTH, StateField.WIDTH]


def _swapped(row: int = 0):
    scenario = make_scenario()
    states = scenario.agents.states.copy()
    states[row][:, SIZE] = states[row][:, SIZE[::-1]]
    return replace(scenario, agents=replace(scenario.agents, states=states))


def test_a_vehicle_wider_than_long_is_turned_round_with_a_warning_naming_the_file(tmp_path):
    scenario = _swapped()
    assert scenario.agents.types[0] == AgentType.VEHICLE
    path = tmp_path / "scene.pkl"
    write_scenarios(path, [scenario])
    with pytest.warns(DataWarning, match=r"scene\.pkl: scenario toy: vehicle @7 \(2\.00 m long, 4\.50 m wide\)"):
        read = read_scenario(path)
    assert np.array_equal(read.agents.states[0][:, SIZE], make_scenario().agents.states[0][:, SIZE])
    assert np.array_equal(read.agents.states[1:], scenario.agents.states[1:])


def test_sane_boxes_and_non_vehicles_are_left_alone(recwarn):
    scenario = make_scenario()
    assert fix_box_sizes(scenario, "x") is scenario
    walker = _swapped(row=1)  # agent 17 is a pedestrian: seen from above, wider than long is possible
    assert walker.agents.types[1] != AgentType.VEHICLE and fix_box_sizes(walker, "x") is walker
    assert not [w for w in recwarn if issubclass(w.category, DataWarning)]
