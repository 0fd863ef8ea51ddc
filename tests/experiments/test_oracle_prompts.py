"""Oracle prompts state each agent's displacement in its own frame; the rewritten dataset trains."""

from __future__ import annotations

import math

import numpy as np
import pytest
from dataset_builders import write_dataset

from langtraj.cli.main import main
from langtraj.errors import InputError
from langtraj.experiments.oracle_prompts import displacement_phrase, oracle_prompts, write_oracle_dataset
from langtraj.interdrive.dataset import iter_records, load_window
from langtraj.model.config import SampleConfig
from langtraj.scenario.types import StateField
from langtraj.training.data import SceneDataset


def test_the_phrase_rounds_to_the_bin_and_names_the_side():
    assert displacement_phrase(33.0, 1.0, 5.0) == "moves about 35 meters forward"
    assert displacement_phrase(12.4, 6.0, 5.0) == "moves about 10 meters forward and 5 meters to the left"
    assert displacement_phrase(-1.0, -13.0, 5.0) == "moves about 0 meters forward and 15 meters to the right"


def test_each_agent_with_a_future_gets_its_own_displacement(tmp_path):
    labels = write_dataset(tmp_path, 2)
    record = next(iter_records(labels))[1][0]
    scene = load_window(record)
    prompts = {p.mentions[0]: p for p in oracle_prompts(scene, bin_m=1.0)}
    c, agents = scene.current_index, scene.agents
    with_future = {int(t) for r, t in enumerate(agents.ids) if agents.valid[r, c] and agents.valid[r, c + 1 :].any()}
    assert set(prompts) == with_future
    row = 0
    track = int(agents.ids[row])
    last = c + 1 + np.flatnonzero(agents.valid[row, c + 1 :])[-1]
    d = agents.states[row, last, :2] - agents.states[row, c, :2]
    h = agents.states[row, c, StateField.HEADING]
    forward = d[0] * math.cos(h) + d[1] * math.sin(h)
    assert f"moves about {round(forward)} meters forward" in prompts[track].roles[track]
    assert prompts[track].roles[track].startswith("the target agent ")


def test_the_rewritten_dataset_reads_and_conditions_agents(tmp_path):
    labels = write_dataset(tmp_path, 4)
    out = tmp_path / "oracle"
    assert main(["experiment", "oracle-prompts", str(labels), "--out", str(out)]) == 0
    dataset = SceneDataset(out, SampleConfig(max_agents=8, max_polylines=12, points_per_polyline=10), split="all")
    texts = [t for i in range(len(dataset)) for t in dataset[i]["text"] if t is not None]
    assert texts and all(t.startswith("the target agent moves about") for t in texts)


def test_bad_arguments_are_refused(tmp_path, capsys):
    labels = write_dataset(tmp_path, 1)
    with pytest.raises(InputError, match="another folder"):
        write_oracle_dataset(labels, labels)
    assert main(["experiment", "oracle-prompts", str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    assert "missing" in capsys.readouterr().err
    with pytest.raises(InputError, match="bin must be positive"):
        oracle_prompts(load_window(next(iter_records(labels))[1][0]), 0.0)
