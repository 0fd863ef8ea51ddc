"""Stopping the studio server mid-job, as a user does (Ctrl-C) and as a crash does (SIGKILL): the job's folder
holds only complete files, and the next studio lists the job as interrupted (docs/studio.md, 'Jobs')."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest

pytest.importorskip("uvicorn", reason="the studio needs uvicorn (the label extra)")

SCENE = "sd_training.tfrecord-00000-of-01000_2a1e44d405a6833f.pkl"


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _get(url: str, timeout: float = 2.0) -> dict:
    with urllib.request.urlopen(url, timeout=timeout) as response:
        return json.loads(response.read())


def _post(url: str, body: dict) -> dict:
    request = urllib.request.Request(url, json.dumps(body).encode(), {"Content-Type": "application/json"})
    with urllib.request.urlopen(request, timeout=10) as response:
        return json.loads(response.read())


class Studio:
    """`langtraj studio FILE --data DATA` in a process of its own, on a free port."""

    def __init__(self, scene: Path, data: Path):
        self.url = f"http://127.0.0.1:{(port := _port())}"
        command = [sys.executable, "-m", "langtraj.cli.main", "studio", str(scene), "--data", str(data)]
        self.process = subprocess.Popen([*command, "--port", str(port)], stderr=subprocess.PIPE)
        deadline = time.monotonic() + 60
        while True:
            try:
                self.scenes = _get(f"{self.url}/api/scenes")["scenes"]
                return
            except OSError:
                if self.process.poll() is not None or time.monotonic() > deadline:
                    tail = self.process.stderr.read().decode()[-500:]
                    raise RuntimeError(f"the studio did not start: {tail}") from None
                time.sleep(0.2)

    def running_job(self) -> str:
        """Start a job and wait until it runs (its first replan counted)."""
        job = _post(
            f"{self.url}/api/jobs",
            {"scene": self.scenes[0]["key"], "prompts": [], "rollouts": 8, "compare": False, "planner": None},
        )["job"]
        deadline = time.monotonic() + 120
        while (now := _get(f"{self.url}/api/jobs/{job['id']}"))["progress"] <= 0 or now["status"] != "running":
            assert now["status"] in ("queued", "running") and time.monotonic() < deadline, now
            time.sleep(0.1)
        return job["id"]

    def stop(self, sig: int) -> None:
        self.process.send_signal(sig)
        self.process.wait(timeout=60)


def _complete(folder: Path) -> None:
    """Every file of a job folder is whole: no temporary file, job.json parses."""
    names = sorted(p.name for p in folder.iterdir())
    assert not [n for n in names if ".tmp" in n], names
    json.loads((folder / "job.json").read_text())


# The kill is slow-marked (1 min; `pytest -m slow`): ctrl-c runs the same job and checks the same files by default.
@pytest.mark.parametrize(
    "sig", [signal.SIGINT, pytest.param(signal.SIGKILL, marks=pytest.mark.slow)], ids=["ctrl-c", "kill"]
)
def test_a_server_stopped_mid_job_leaves_whole_files_and_an_interrupted_job(real_data_dir, tmp_path, sig):
    if os.name != "posix":
        pytest.skip("POSIX signals")
    studio = Studio(real_data_dir / SCENE, tmp_path)
    job = studio.running_job()
    studio.stop(sig)
    folder = tmp_path / "jobs" / job
    if sig == signal.SIGINT:  # a graceful stop cleans up after itself
        _complete(folder)
    again = Studio(real_data_dir / SCENE, tmp_path)  # a crash's leftovers are removed at start-up
    try:
        _complete(folder)
        listed = _get(f"{again.url}/api/jobs/{job}")
        assert listed["status"] == "interrupted" and listed["error"]
    finally:
        again.stop(signal.SIGINT)
