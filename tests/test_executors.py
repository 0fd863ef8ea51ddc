"""The process executor's workers share the machine's cores (langtraj.executors.share_cores)."""

from __future__ import annotations

import os

import pytest
import torch

from langtraj.executors import THREAD_VARIABLES, ProcessExecutor, share_cores


@pytest.fixture
def clean_threads(monkeypatch):
    for name in THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    threads = torch.get_num_threads()
    yield monkeypatch
    torch.set_num_threads(threads)


@pytest.mark.parametrize(("cores", "workers", "expected"), [(2, 2, 1), (16, 4, 4), (2, 3, 1), (8, 1, 8)])
def test_each_worker_gets_its_share_of_the_cores(clean_threads, cores, workers, expected):
    clean_threads.setattr(os, "cpu_count", lambda: cores)
    assert share_cores(workers) == expected
    assert all(os.environ[name] == str(expected) for name in THREAD_VARIABLES)
    assert torch.get_num_threads() == expected  # torch was already loaded: told directly


def test_a_thread_count_the_user_set_wins(clean_threads):
    clean_threads.setattr(os, "cpu_count", lambda: 8)
    clean_threads.setenv("OMP_NUM_THREADS", "3")
    assert share_cores(2) == 3
    assert torch.get_num_threads() == 3


def test_pool_workers_start_with_their_share(monkeypatch):
    for name in THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    share = max(1, (os.cpu_count() or 1) // 2)
    assert list(ProcessExecutor().map(os.getenv, ["OMP_NUM_THREADS"] * 2, workers=2)) == [str(share)] * 2
