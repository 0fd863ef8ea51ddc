"""The training-memory benchmark (benchmarks/train_memory.py; docs/benchmarks.md, 'Training memory (issue 28,
2026-11-26)'): its counting, its CUDA casting policy, and whole runs on the tiny and gpu-short presets."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest
import torch

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "train_memory.py"
H200_PEAK_GIB = 7.7
"""The peak a user measured for configs/gpu-short.yaml's model and batch in bf16-mixed on an H200 (issue 28)."""


@pytest.fixture(scope="module")
def bench(monkeypatch_module):
    monkeypatch_module.syspath_prepend(str(SCRIPT.parent))  # the script imports its sibling `synthetic`
    spec = importlib.util.spec_from_file_location("train_memory", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as patch:
        yield patch


def test_live_bytes_follow_allocations_and_releases_and_count_views_once(bench):
    x = torch.ones(1000, requires_grad=True)
    with bench.LiveBytes() as live:
        y = x * 2  # 4,000 bytes
        view = y.view(10, 100)
        z = (view * 3).sum()  # 4,000 bytes freed once summed, and 4 for the sum
        assert live.live == 4004
        z.backward()
        del y, view, z
    assert live.live < 4004 <= live.peak < 4004 + 3 * 4000


def test_the_cuda_policy_runs_layer_norm_and_softmax_in_float32_under_autocast(bench):
    x = torch.randn(4, 8)
    with torch.autocast("cpu", dtype=torch.bfloat16):
        plain = torch.nn.functional.layer_norm(torch.nn.functional.linear(x, torch.randn(8, 8)), (8,))
        with bench.cuda_float32_policy():
            h = torch.nn.functional.linear(x, torch.randn(8, 8))
            normed, soft = torch.nn.functional.layer_norm(h, (8,)), torch.softmax(h, -1)
    assert plain.dtype == torch.bfloat16 and h.dtype == torch.bfloat16
    assert normed.dtype == soft.dtype == torch.float32
    assert torch.nn.functional.layer_norm(x, (8,)).dtype == torch.float32  # restored


def test_the_fit_is_a_least_squares_line(bench):
    assert bench.fit([1, 2], [3.0, 5.0]) == pytest.approx((1.0, 2.0))
    assert bench.fit([1, 2, 4], [3.0, 5.0, 9.0]) == pytest.approx((1.0, 2.0))
    assert bench.fit([2], [6.0]) == pytest.approx((0.0, 3.0))


def test_the_tiny_preset_prints_a_table_and_its_peak_last():
    out = subprocess.run(
        [sys.executable, str(SCRIPT), "--config", str(ROOT / "configs" / "tiny.yaml")],
        capture_output=True, text=True, check=True, timeout=300,
    )  # fmt: skip
    lines = out.stdout.strip().splitlines()
    assert any(line.startswith("parameters (fp32)") for line in lines)
    match = re.fullmatch(r"peak GiB: (\d+\.\d\d)", lines[-1])
    assert match and float(match.group(1)) > 0


def test_the_gpu_short_estimate_matches_the_peak_measured_on_an_h200(bench, one_torch_thread):
    """Calibration: the count before the allowance is within 10 % of a real GPU's allocator peak."""
    said: list[str] = []
    peak = bench.run(ROOT / "configs" / "gpu-short.yaml", [1, 2], None, say=said.append)
    total = float(next(line for line in said if line.startswith("total")).split()[-1])
    assert total == pytest.approx(H200_PEAK_GIB, rel=0.1)
    assert peak == pytest.approx(total * bench.ALLOWANCE_FACTOR + bench.ALLOWANCE_GIB, abs=0.01)
    assert said[-1] == f"peak GiB: {peak:.2f}"
