"""A job's per-agent events agree with its realism figures: each first contact with its step and partner, the
table's collision rate over the evaluated agents equal to WOSAC's, and off-road saying what it is measured against
("not measured" without road edges); the RUN object carries the prompted agents' series (`test_series.py`)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from langtraj.interdrive.adherence import AdherenceChecker
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.reader import PromptReading
from langtraj.interdrive.targets import derive_target
from langtraj.metrics.controllability import collision_events, collision_rate
from langtraj.roads import MapIndex
from langtraj.rollouts.agents import evaluated_agent_indices
from langtraj.rollouts.baselines import generate_baseline
from langtraj.scenario.io import read_scenario
from langtraj.scenario.model import RoadMap
from langtraj.sim.failures import log_rollouts
from langtraj.studio.results import agent_outcomes, realism, road_edges, run_json, table_rates
from langtraj.studio.series import prompted_series

CONTACT_STEP = 30


@pytest.fixture(scope="module")
def rammed(real_data_dir: Path):
    """The WOMD scene's logged future as two rollouts, in the second of which an evaluated agent is put onto
    another agent's pose from step 30 on."""
    scenario = read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord")
    log = log_rollouts(scenario)
    two = {k: np.concatenate([getattr(log, k)] * 2) for k in ("x", "y", "z", "heading")}
    ids = list(log.object_id)
    evaluated = [int(i) for i in scenario.agents.ids[evaluated_agent_indices(scenario)]]
    mover, struck = evaluated[0], next(i for i in ids if int(i) != evaluated[0] and int(i) not in evaluated)
    a, b = ids.index(mover), ids.index(struck)
    for key in ("x", "y", "heading"):
        two[key][1, a, CONTACT_STEP:] = two[key][1, b, CONTACT_STEP:]
    return scenario, replace(log, **two, log_following_ids=None), mover, int(struck)


def test_a_contact_is_listed_with_its_step_and_partner(rammed) -> None:
    scenario, rollouts, mover, struck = rammed
    events = [(e.rollout, e.agent, e.other) for e in collision_events(scenario, rollouts)]
    assert (1, mover, struck) in events and (1, struck, mover) in events
    assert (0, mover, struck) not in events
    rows = {a["id"]: a for a in agent_outcomes(scenario, rollouts)}
    (contact,) = [c for c in rows[mover]["collisions"] if c["rollout"] == 1]
    assert contact == {"rollout": 1, "step": CONTACT_STEP, "with": struck}
    assert rows[mover]["collision"] == [False, True] and rows[mover]["evaluated"]


def test_the_tables_rate_over_evaluated_agents_is_wosacs(rammed) -> None:
    scenario, rollouts, _, _ = rammed
    agents = agent_outcomes(scenario, rollouts)
    rates, figures = table_rates(agents), realism(scenario, rollouts)
    assert figures["evaluated"] == sum(a["evaluated"] for a in agents)
    assert rates["collision_evaluated"] == pytest.approx(figures["collision_rate"], abs=1e-4)
    assert rates["collision_evaluated"] > 0
    assert rates["collision_all"] == pytest.approx(collision_rate(scenario, rollouts), abs=1e-4)


def test_the_flow_beside_realism_is_the_logs_own_on_the_log(rammed) -> None:
    """The log replayed drives as fast as the log and ends stopped as often (`metrics.flow`), shown beside WOSAC's."""
    scenario = rammed[0]
    figures = realism(scenario, log_rollouts(scenario))
    assert figures["moving_vehicles_speed_vs_log"] == pytest.approx(1.0, abs=1e-3)
    assert figures["moving_vehicles_end_stopped"] == figures["moving_vehicles_end_stopped_in_log"]


def test_offroad_says_what_it_is_measured_against(real_data_dir: Path) -> None:
    """nuScenes maps have no road edges of their own: off-road is measured against edges derived from the lanes
    and says so; a map with neither is not measured."""
    nuscenes = read_scenario(real_data_dir / "sd_nuscenes_v1.0-mini_scene-0061.pkl")
    assert road_edges(nuscenes).startswith("derived from")
    womd = read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord")
    assert road_edges(womd) == "map"
    bare = replace(womd, road_map=RoadMap(()))
    assert road_edges(bare) is None
    agents = agent_outcomes(bare, log_rollouts(bare))
    assert all(f is None for a in agents for f in a["offroad"]) and table_rates(agents)["offroad_all"] is None
    assert all(a["offroads"] == [] for a in agents)


def test_an_offroad_event_has_its_first_step(real_data_dir: Path) -> None:
    """Each rollout in which a vehicle leaves the road lists the first step it is off (as the flag), so the page
    can jump there: a car pushed 30 m sideways from step 25 of rollout 1 is off the road from step 25 there."""
    womd = read_scenario(real_data_dir / "motion_data_one_scenario.tfrecord")
    rollouts = generate_baseline("log_replay", womd, 2)
    agents = {a["id"]: a for a in agent_outcomes(womd, rollouts)}
    car = next(i for i, a in agents.items() if a["offroad"] == [False, False] and not a["parked"])
    k = int(np.flatnonzero(rollouts.object_id == car)[0])
    rollouts.x[1, k, 25:] += 30.0
    rollouts.y[1, k, 25:] += 30.0
    moved = {a["id"]: a for a in agent_outcomes(womd, rollouts)}[car]
    for a in [moved, *agents.values()]:
        assert [o["rollout"] for o in a["offroads"]] == [r for r, f in enumerate(a["offroad"]) if f]
    assert moved["offroads"] == [{"rollout": 1, "step": 25}]


def test_the_run_carries_the_prompted_agents_series(rammed) -> None:
    """The prompt "@mover stops" with its derived stop target in the run's report: the RUN object plots the mover's
    speed and distance to the stop point in both rollouts (`prompted_series`), a prompt not read adds nothing, and
    the whole object is JSON without NaN."""
    scenario, rollouts, mover, _ = rammed
    index = MapIndex.build(scenario.road_map)
    target = derive_target(scenario, mover, Behaviour.STOP, index).to_json()
    readings = [PromptReading(Behaviour.STOP, mover), PromptReading(None, None, reason="no agent named")]
    report = {"prompt": {"targets": [target]}}
    checker = AdherenceChecker.build(scenario, map_index=index)
    run = run_json(scenario, rollouts, ["@m stops", "drive well"], readings, checker, report, 1.0)
    assert list(run["series"]) == [str(mover)]
    entry = run["series"][str(mover)]
    assert entry["goal"] == "the stop point" and entry["to_target"][0][scenario.current_index] > 0  # ahead
    length = scenario.current_index + 1 + rollouts.num_steps
    assert [len(s) for s in entry["speed"]] == [length] * 2 and [len(s) for s in entry["to_target"]] == [length] * 2
    assert entry == prompted_series(scenario, rollouts, [target], [mover])[str(mover)]
    json.dumps(run, allow_nan=False)
