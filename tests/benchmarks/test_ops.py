"""The operation-count benchmarks (benchmarks/train_ops.py, benchmarks/sample_ops.py; docs/benchmarks.md,
'Operations per step') run, count per part, and see the per-window work out of the training step."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BENCHMARKS = ROOT / "benchmarks"
SCENE = ROOT.parent / "shared" / "data" / "real" / "sd_training.tfrecord-00000-of-01000_2a1e44d405a6833f.pkl"

INVERSE_DYNAMICS_OPS = 20_000
"""About what fitting a batch's target actions inside the step added (22,322 operations measured, whatever the
batch size): a tiny network step above this means the fit is back in the step."""


def _run(*args: str) -> list[str]:
    env = {**os.environ, "HF_HUB_OFFLINE": "1"}
    out = subprocess.run([sys.executable, *args], capture_output=True, text=True, cwd=BENCHMARKS, env=env, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.strip().splitlines()


def test_train_ops_counts_a_tiny_step_by_part_without_the_target_fit():
    lines = _run("train_ops.py", "--config", str(ROOT / "configs" / "tiny.yaml"), "--batch", "2", "--top", "5")
    total = re.fullmatch(r"aten ops per step: (\d+)", lines[-1])
    assert total, lines[-1]
    parts = {m[1]: int(m[2]) for line in lines if (m := re.fullmatch(r"(.+): (\d+) aten ops", line))}
    assert set(parts) == {"network (forward, backward)", "gradient clipping", "optimizer"}
    assert sum(parts.values()) == int(total[1])
    assert 1_000 < parts["network (forward, backward)"] < INVERSE_DYNAMICS_OPS / 2
    assert lines[0].startswith("tiny: batch 2, cpu, precision 32-true, compile off")


# Slow (2 min: a whole simulation under the profiler); `pytest -m slow`.
@pytest.mark.slow
@pytest.mark.skipif(not SCENE.is_file(), reason=f"needs the real scene {SCENE.name} in ../shared/data/real")
def test_sample_ops_counts_the_denoising_and_guidance_steps_of_a_simulation():
    lines = _run("sample_ops.py", "--agents", "16", "--rollouts", "1", "--top", "3")
    assert lines[0].startswith("16 agents (16 driven), 1 rollouts x 4 candidates, K = 5, cpu, denoiser eager: ")
    assert "40 denoising steps, 24 guided" in lines[0]  # 8 replans x 5 steps, the last 3 of each guided
    guidance = re.fullmatch(r"aten ops per guidance step: (\d+)", lines[-2])
    step = re.fullmatch(r"aten ops per denoising step: (\d+)", lines[-1])
    assert guidance and step, lines[-2:]
    assert 100 < int(step[1]) < 5_000 and int(guidance[1]) > 0
