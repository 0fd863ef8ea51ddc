"""Several processes (Lightning DDP, gloo on CPU): each takes its own share of the batch stream, a
two-process run trains and resumes exactly, by configuration alone."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch
import yaml
from dataset_builders import TINY_TRAINING, write_dataset

from langtraj.model.checkpoint import read_checkpoint
from langtraj.training.module import RankShare


class _Stream(torch.utils.data.Sampler[int]):
    def __iter__(self):
        return itertools.count()


def _take(sampler, count: int) -> list[int]:
    return list(itertools.islice(iter(sampler), count))


def test_one_process_gets_the_stream_after_the_steps_already_trained():
    assert _take(RankShare(_Stream(), 4), 6) == [0, 1, 2, 3, 4, 5]
    assert _take(RankShare(_Stream(), 4, skip_steps=3), 4) == [12, 13, 14, 15]


def test_processes_take_disjoint_batches_whose_union_is_the_stream():
    batch, world, steps = 3, 4, 5
    shares = [
        _take(RankShare(_Stream(), batch, rank=r, world=world, skip_steps=2), batch * steps) for r in range(world)
    ]
    for step in range(steps):
        rows = [i for share in shares for i in share[step * batch : (step + 1) * batch]]
        assert rows == list(range((2 + step) * world * batch, (3 + step) * world * batch))


def test_a_bad_share_is_refused():
    for kwargs in ({"rank": 2, "world": 2}, {"world": 0}, {"skip_steps": -1}):
        with pytest.raises(ValueError, match="bad share"):
            RankShare(_Stream(), 4, **kwargs)


def _train(config: Path, labels: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, PL_DISABLE_FORK="1", OMP_NUM_THREADS="1")
    command = [sys.executable, "-m", "langtraj.cli.main", "train", "--config", str(config), "--data", str(labels)]
    return subprocess.run(
        [*command, "--out", str(out), *extra], env=env, capture_output=True, text=True, timeout=300, check=False
    )


# Slow (1.5 min: two training processes); `pytest -m slow`. The one-process resume is in the default run.
@pytest.mark.slow
def test_two_processes_train_and_resume_exactly(tmp_path):
    labels = write_dataset(tmp_path, 12)
    config = tmp_path / "ddp.yaml"
    settings = {"accelerator": "cpu", "devices": 2, "strategy": "ddp", "max_steps": 4, "checkpoint_every_steps": 2}
    config.write_text(yaml.safe_dump({**TINY_TRAINING, **settings}))

    whole = _train(config, labels, tmp_path / "whole")
    assert whole.returncode == 0, whole.stderr[-3000:]
    assert whole.stdout.count("last checkpoint") == 1  # printed by rank 0 only
    middle = tmp_path / "whole" / "checkpoints" / "step0000002.ckpt"
    resumed = _train(config, labels, tmp_path / "resumed", "--resume", str(middle))
    assert resumed.returncode == 0, resumed.stderr[-3000:]

    a = read_checkpoint(tmp_path / "whole" / "checkpoints" / "last.ckpt")
    b = read_checkpoint(tmp_path / "resumed" / "checkpoints" / "last.ckpt")
    assert a["global_step"] == b["global_step"] == 4
    start = read_checkpoint(middle)["state_dict"]
    moved = [k for k, v in a["state_dict"].items() if not torch.equal(v, start[k])]
    assert moved  # steps 3 and 4 trained something
    for key, value in a["state_dict"].items():
        torch.testing.assert_close(b["state_dict"][key], value, atol=1e-6, rtol=1e-5, msg=key)
