"""`langtraj train` and `langtraj sample` end to end on toy scenes with a tiny model."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from dataset_builders import TINY_TRAINING as TINY
from dataset_builders import train_tiny, write_dataset

from langtraj.cli.main import main
from langtraj.model.checkpoint import load_model, read_checkpoint
from langtraj.scenario.io import read_scenario
from langtraj.sim.open_loop import sample_open_loop


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> tuple[Path, Path]:
    return train_tiny(tmp_path_factory.mktemp("cli"))


def test_train_writes_checkpoints_and_logs(trained):
    checkpoint, _ = trained
    run = checkpoint.parents[1]
    assert checkpoint.is_file() and (run / "checkpoints" / "step0000002.ckpt").is_file()
    assert list((run / "logs").rglob("events.out.tfevents*")) and list((run / "logs").rglob("metrics.csv"))


def test_sample_renders_a_video_per_sample_and_saves_states(trained, tmp_path, capsys):
    checkpoint, scenes = trained
    out, npz = tmp_path / "s.gif", tmp_path / "s.npz"
    code = main(["sample", str(scenes), "--checkpoint", str(checkpoint), "--out", str(out), "--samples", "2",
                 "--steps", "2", "--prompt", "@7 turns left", "--npz", str(npz)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert (tmp_path / "s_s0.gif").stat().st_size > 0 and (tmp_path / "s_s1.gif").stat().st_size > 0
    saved = np.load(npz)
    assert saved["states"].shape[:1] == (2,) and 7 in saved["agents"].tolist()


def test_prompted_agents_are_the_conditioned_ones(trained):
    checkpoint, scenes = trained
    model, data = load_model(checkpoint)
    scenario = read_scenario(scenes)
    result = sample_open_loop(model, scenario, data, prompt="@7 yields to @17", steps=2)
    assert result.conditioned == (7, 17)
    shown = result.scenario_with(scenario)
    assert shown.agents.valid[result.agents, scenario.current_index + 1 :].all()


@pytest.mark.parametrize(
    ("prompt", "message"), [("@999 turns left", "unknown agent @999"), ("", "empty prompt"), ("@7", "describes no")]
)
def test_bad_prompts_are_refused_without_output(trained, tmp_path, capsys, prompt, message):
    checkpoint, scenes = trained
    out = tmp_path / "s.png"
    code = main(["sample", str(scenes), "--checkpoint", str(checkpoint), "--out", str(out), "--prompt", prompt])
    assert code == 2 and message in capsys.readouterr().err and not out.exists()


def test_a_checkpoint_that_is_not_langtraj_is_refused(trained, tmp_path, capsys):
    _, scenes = trained
    bad = tmp_path / "bad.ckpt"
    bad.write_bytes(b"\x00" * 10)
    code = main(["sample", str(scenes), "--checkpoint", str(bad), "--out", str(tmp_path / "s.png")])
    assert code == 2 and "bad.ckpt" in capsys.readouterr().err


def test_a_killed_run_resumes_from_its_last_checkpoint(tmp_path):
    """SIGKILL in the middle of training: every checkpoint on disk is whole, and --resume auto goes on
    from the newest one."""
    import signal
    import subprocess
    import sys
    import time

    labels = write_dataset(tmp_path, 12)
    config = tmp_path / "tiny.yaml"
    config.write_text(yaml.safe_dump({**TINY, "stage": 1, "model": {**TINY["model"], "use_text": False},
                                      "max_steps": 100000, "checkpoint_every_steps": 2}))  # fmt: skip
    run = tmp_path / "run"
    cmd = [sys.executable, "-m", "langtraj.cli.main", "train", "--config", str(config), "--data", str(labels)]
    proc = subprocess.Popen([*cmd, "--out", str(run)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not list(run.glob("checkpoints/step*.ckpt")) and time.monotonic() < deadline:
            time.sleep(0.2)
        time.sleep(1.0)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    saved = sorted(run.glob("checkpoints/**/*.ckpt"))  # what users glob: partial writes must not match
    assert saved, "no checkpoint was written before the kill"
    steps = [read_checkpoint(p)["global_step"] for p in saved]  # every file on disk loads
    newest = max(steps)
    assert main(["train", "--config", str(config), "--data", str(labels), "--out", str(run), "--resume", "auto",
                 "--max-steps", str(newest + 2)]) == 0  # fmt: skip
    assert read_checkpoint(run / "checkpoints" / "last.ckpt")["global_step"] == newest + 2
