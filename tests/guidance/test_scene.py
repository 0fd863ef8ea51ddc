"""GuidanceScene built from a Scenario (the whole map) and from a SceneBatch row (what the model sees)."""

from __future__ import annotations

import math

import pytest
import torch
from scenario_builders import make_scenario

from langtraj.errors import InputError
from langtraj.guidance import GuidanceScene, KeepLaneCost, OnRoadCost
from langtraj.model.config import SampleConfig
from langtraj.model.features import collate_scenes, scene_frame, scene_sample
from langtraj.scenario.types import MapFeatureType


def test_from_scenario_transforms_the_map_and_pads_the_agents():
    scenario = make_scenario(4)  # two 41-point lanes, two 41-point road edges along x
    scene = GuidanceScene.from_scenario(scenario, (10.0, 0.0, math.pi / 2), [1, 0, 2], num_agents=5, max_lane_points=20)
    assert scene.road_edges.shape == (80, 2, 2)
    assert scene.lanes.shape == (6, 20, 2)  # each lane: 20 + 20 + 3 points, sharing end points
    start, end = scene.lane_segments()
    assert start.shape == (80, 2) and torch.allclose(start[1:40], end[:39])  # no segment lost at the cuts
    # World (-50, 0) is 60 m west of the origin, which faces north: 60 m to its left, (0, 60).
    assert torch.allclose(scene.lanes[0, 0], torch.tensor([0.0, 60.0]), atol=1e-4)
    assert scene.agent_valid.tolist() == [True, True, False, False, False]  # agent 2 appears late; padding
    assert scene.agent_size[0].tolist() == pytest.approx([4.5, 2.0])
    assert scene.agent_size[2:].abs().max() == 0
    assert scene.to("cpu").lanes.data_ptr() == scene.lanes.data_ptr()


def test_the_road_from_a_scenario_keeps_its_side():
    scenario = make_scenario(2)
    origin = scene_frame(scenario)
    scene = GuidanceScene.from_scenario(scenario, origin, [0, 1])
    # Agent 0 drives on the lane at y = 0 between edges at y = -1.75 and 5.25: on the road, on a lane.
    x0 = float(scenario.agents.states[0, scenario.current_index, 0]) - origin[0]
    on = torch.tensor([[[x0, 0.0, 0.0, 5.0]]]).expand(1, 2, 3, 4).clone()
    off = on.clone()
    off[..., 1] = -4.0
    assert OnRoadCost(margin=1.0)(on, scene).item() == 0
    assert OnRoadCost(margin=1.0)(off, scene).item() > 0
    assert KeepLaneCost()(on, scene).item() == pytest.approx(0.0, abs=1e-3)  # the log has centimetre noise


def test_from_scenario_can_keep_only_the_map_near_the_origin():
    scene = GuidanceScene.from_scenario(make_scenario(2), (10.0, 0.0, 0.0), [0], radius=1.0)
    assert scene.road_edges.shape[0] == 0  # the edges are 1.75 m away
    assert scene.lanes.shape[0] == 3  # only the lane through the origin


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"agent_indices": [0, 9]}, r"agent indices must be in \[0, 2\)"),
        ({"agent_indices": [0, 1], "num_agents": 1}, "num_agents 1 is less than the 2 agent indices"),
        ({"agent_indices": [0], "max_lane_points": 1}, "max_lane_points must be >= 2"),
        ({"agent_indices": [0], "origin": (0.0, 0.0)}, r"origin must be \(x, y, heading\)"),
    ],
)
def test_from_scenario_refuses_bad_arguments(kwargs, message):
    args = {"origin": (0.0, 0.0, 0.0), **kwargs}
    with pytest.raises(InputError, match=message):
        GuidanceScene.from_scenario(make_scenario(2), **args)


def test_from_batch_takes_the_lanes_and_edges_the_model_sees():
    config = SampleConfig(max_agents=6, max_polylines=16, points_per_polyline=10, text=False)
    sample = scene_sample(make_scenario(3), config)
    batch = collate_scenes([sample, sample])
    scene = GuidanceScene.from_batch(batch, 1)
    types = [MapFeatureType(t) for t in batch.map_type[1].tolist() if t > 0]
    assert scene.lanes.shape[0] == sum(t.is_lane for t in types) > 0
    assert scene.road_edges.shape[0] > 0
    assert scene.agent_valid.tolist() == batch.agent_valid[1].tolist()
    # Road-edge pieces keep their direction: the lower edge (y = -1.75 in the world) still runs east.
    lower = scene.road_edges[scene.road_edges[:, :, 1].mean(-1) < 0]
    assert (lower[:, 1, 0] > lower[:, 0, 0]).all()
    with pytest.raises(InputError, match=r"row 2 is outside \[0, 2\)"):
        GuidanceScene.from_batch(batch, 2)


def test_badly_shaped_tensors_are_refused():
    good = {
        "road_edges": torch.zeros(0, 2, 2),
        "lanes": torch.zeros(1, 3, 2),
        "lane_valid": torch.ones(1, 3, dtype=torch.bool),
        "agent_size": torch.zeros(2, 2),
        "agent_valid": torch.ones(2, dtype=torch.bool),
    }
    GuidanceScene(**good)
    with pytest.raises(InputError, match="road_edges must be"):
        GuidanceScene(**{**good, "road_edges": torch.zeros(3, 2)})
    with pytest.raises(InputError, match="lanes must be"):
        GuidanceScene(**{**good, "lane_valid": torch.ones(1, 2, dtype=torch.bool)})
    with pytest.raises(InputError, match="agent_size must be"):
        GuidanceScene(**{**good, "agent_valid": torch.ones(3, dtype=torch.bool)})
