"""Fixtures of the closed-loop prompt tests: the shipped checkpoint, and a constructed four-way junction with two cars
driving straight through it, 6 m/s, one in each lane of one approach."""

from __future__ import annotations

import pytest
from interdrive.test_counterfactual import LEFT_LANE_STRAIGHT, RIGHT_LANE_STRAIGHT, drive, four_way
from interdrive.test_heuristics import scene

from langtraj.model.checkpoint import load_model
from langtraj.sim.checkpoints import shipped_checkpoint


@pytest.fixture(scope="module")
def loaded():
    return load_model(shipped_checkpoint())


@pytest.fixture(scope="module")
def junction():
    return scene(four_way(), drive(LEFT_LANE_STRAIGHT, speed=6.0), drive(RIGHT_LANE_STRAIGHT, speed=6.0, start=20.0))
