"""The JSON-lines protocol: encoding, the served planner against the in-process one, and misbehaving planners."""

from __future__ import annotations

import io
import json
import shlex
import sys
import textwrap
import time

import numpy as np
import pytest

from langtraj.env.spaces import EgoColumn, observation_space
from langtraj.planners import (
    IDMPlanner,
    LogReplayPlanner,
    PlannerError,
    PlannerTimeout,
    SubprocessPlanner,
    decode_observation,
    encode_observation,
    reset_planner,
    serve,
)
from langtraj.planners.jsonlines import decode_info, encode_info

from .helpers import left_curve, make_observation, vehicle

PYTHON = shlex.quote(sys.executable)
SERVE = f"{PYTHON} -m langtraj.planners.serve"


def _observations() -> list[dict[str, np.ndarray]]:
    return [
        make_observation(speed=8.0),
        make_observation(speed=10.0, agents=[vehicle(20.0, speed=3.0)]),
        make_observation(speed=12.0, route=left_curve(), lights=[(30.0, 0.0, 4)]),
        make_observation(speed=5.0, route=np.zeros((0, 2))),
    ]


def _script(tmp_path, source: str) -> str:
    """A command running `source` as a Python script."""
    path = tmp_path / "planner.py"
    path.write_text(textwrap.dedent(source))
    return f"{PYTHON} {shlex.quote(str(path))}"


def test_observations_round_trip_through_json():
    obs = {key: value for key, value in observation_space().sample().items()}
    obs["ego"][EgoColumn.HEADING] = np.nan  # non-finite values travel as null
    data = json.loads(json.dumps(encode_observation(obs), allow_nan=False))
    back = decode_observation(data)
    assert set(back) == set(obs)
    for key, value in obs.items():
        assert back[key].dtype == value.dtype and back[key].shape == value.shape, key
        np.testing.assert_array_equal(back[key], value)
    assert observation_space().contains(decode_observation(encode_observation(make_observation())))


def test_info_round_trips_with_nan_as_null():
    logged = np.arange(320, dtype=np.float64).reshape(80, 4)
    logged[70:] = np.nan
    info = {"scenario_id": "abc", "ego_id": np.int64(7), "step_seconds": 0.1, "logged_ego": logged}
    text = json.dumps(encode_info(info), allow_nan=False)
    assert "null" in text
    back = decode_info(json.loads(text))
    assert back["scenario_id"] == "abc" and back["ego_id"] == 7
    np.testing.assert_array_equal(back["logged_ego"], logged)


def test_serve_answers_each_message_with_one_line():
    obs = make_observation(agents=[vehicle(20.0)])
    messages = [
        {"type": "hello", "protocol": 1},
        {"type": "reset", "observation": encode_observation(obs), "info": {"scenario_id": "s", "step_seconds": 0.1}},
        {"type": "act", "observation": encode_observation(obs)},
        {"type": "close"},
        {"type": "act", "observation": encode_observation(obs)},  # after close: not read
    ]
    out = io.StringIO()
    serve(IDMPlanner(), io.StringIO("".join(json.dumps(m) + "\n" for m in messages)), out)
    replies = [json.loads(line) for line in out.getvalue().splitlines()]
    assert replies[:2] == [{"action_kind": "control", "reads_log": False}, {}] and len(replies) == 3
    np.testing.assert_allclose(replies[2]["action"], IDMPlanner().act(obs), rtol=1e-6)


def test_a_served_idm_acts_like_the_in_process_one():
    planner = SubprocessPlanner(f"{SERVE} idm", timeout_s=30.0)
    try:
        assert planner.action_kind == "control"
        local = IDMPlanner()
        for obs in _observations():
            info = {"scenario_id": "s", "ego_id": 1, "step_seconds": 0.1, "logged_ego": np.full((80, 4), np.nan)}
            planner.reset(obs, info)
            local.reset(obs, info)
            action = planner.act(obs)
            assert action.dtype == np.float32
            np.testing.assert_array_equal(action, local.act(obs))
    finally:
        planner.close()
    assert planner._process.poll() == 0  # it exited on close
    planner.close()  # twice is fine


def test_a_served_log_replay_gets_the_log_through_the_info():
    logged = np.stack([0.5 * np.arange(1, 81), np.zeros(80), np.zeros(80), np.full(80, 5.0)], axis=1)
    logged[60:] = np.nan
    obs = make_observation(time=0.0)
    planner = SubprocessPlanner(f"{SERVE} log_replay", timeout_s=30.0)
    try:
        assert planner.action_kind == "trajectory"
        planner.reset(obs, {"logged_ego": logged, "step_seconds": 0.1})
        local = LogReplayPlanner()
        local.reset(obs, {"logged_ego": logged, "step_seconds": 0.1})
        for t in (0.0, 5.5, 7.0):
            step = make_observation(time=t, pose=(0.5 * round(t * 10), 0.0, 0.0))
            np.testing.assert_allclose(planner.act(step), local.act(step), atol=1e-6)
    finally:
        planner.close()


def test_serve_rejects_a_bad_spec_in_one_line(tmp_path):
    with pytest.raises(PlannerError) as caught:
        SubprocessPlanner(f"{SERVE} nonexistent", timeout_s=30.0, stderr_path=tmp_path / "stderr.txt")
    message = str(caught.value)
    assert "exited (code 2) during hello" in message and "unknown planner 'nonexistent'" in message
    assert "\n" not in message
    assert "unknown planner" in (tmp_path / "stderr.txt").read_text()


def test_a_planner_that_hangs_times_out(tmp_path):
    command = f'{PYTHON} -c "import time,sys; sys.stdin.readline(); time.sleep(60)"'
    start = time.monotonic()
    with pytest.raises(PlannerTimeout, match=r"did not answer hello within 1 s"):
        SubprocessPlanner(command, timeout_s=1.0)
    assert time.monotonic() - start < 30  # cut short, not waited out (the planner sleeps 60 s): no speed limit


def test_a_planner_that_hangs_mid_episode_times_out_and_is_killed(tmp_path):
    command = _script(
        tmp_path,
        """
        import sys, time
        sys.stdin.readline()
        print('{"action_kind": "control"}', flush=True)
        time.sleep(60)
        """,
    )
    planner = SubprocessPlanner(command, timeout_s=1.0)
    start = time.monotonic()
    with pytest.raises(PlannerTimeout):
        planner.reset(make_observation(), {})  # never answered
    with pytest.raises(PlannerError, match="failed reset earlier"):
        planner.act(make_observation())
    planner.close()
    assert time.monotonic() - start < 30 and planner._process.poll() is not None  # cut short and killed


@pytest.mark.parametrize(
    ("reply", "expected"),
    [
        ("garbage", "answered act with a line that is not JSON: garbage"),
        ("[1, 2]", "answered act with JSON that is not an object"),
        ('{"acceleration": 1}', 'answered act without "action"'),
        ('{"action": [1, 2, 3]}', "an action of shape (3,), expected (2,)"),
        ('{"action": ["a", "b"]}', "an action that is not an array of numbers (list)"),
        ('{"action": [1, null]}', "a non-finite action"),  # the one rule of env.spaces.checked_action
    ],
)
def test_bad_replies_raise_planner_errors(tmp_path, reply, expected):
    command = _script(
        tmp_path,
        f"""
        import sys
        for line in sys.stdin:
            kind = line.split('"type":')[1].split('"')[1]
            sys.stderr.write("got " + kind + "\\n")
            print({{"hello": '{{"action_kind": "control"}}', "reset": "{{}}", "act": {reply!r}}}[kind], flush=True)
        """,
    )
    planner = SubprocessPlanner(command, timeout_s=10.0, stderr_path=tmp_path / "stderr.txt")
    try:
        planner.reset(make_observation(), {})
        with pytest.raises(PlannerError) as caught:
            planner.act(make_observation())
    finally:
        planner.close()
    message = str(caught.value)
    assert expected in message and "\n" not in message
    assert message.endswith("its last stderr line: got act")


def test_a_planner_that_crashes_is_reported_with_its_last_stderr_line(tmp_path):
    command = _script(
        tmp_path,
        """
        import sys
        sys.stdin.readline()
        print('{"action_kind": "control"}', flush=True)
        sys.stdin.readline()
        raise ValueError("bad observation")
        """,
    )
    planner = SubprocessPlanner(command, timeout_s=10.0, stderr_path=tmp_path / "stderr.txt")
    with pytest.raises(PlannerError) as caught:
        planner.reset(make_observation(), {})
    planner.close()
    assert "exited (code 1) during reset; its last stderr line: ValueError: bad observation" in str(caught.value)


def test_a_command_that_cannot_start_raises_planner_error():
    with pytest.raises(PlannerError, match="cannot start planner"):
        SubprocessPlanner("/no/such/planner --flag")
    with pytest.raises(PlannerError, match="empty"):
        SubprocessPlanner("  ")


def test_served_planners_may_print(tmp_path, monkeypatch):
    (tmp_path / "chatty.py").write_text(
        "import numpy as np\n"
        "class Chatty:\n"
        "    def reset(self, observation):\n"
        "        print('resetting')\n"
        "    def act(self, observation):\n"
        "        print('acting')\n"
        "        return np.array([0.5, 0.0])\n"
    )
    command = f"env PYTHONPATH={shlex.quote(str(tmp_path))} {SERVE} chatty:Chatty"
    planner = SubprocessPlanner(command, timeout_s=30.0, stderr_path=tmp_path / "stderr.txt")
    try:
        planner.reset(make_observation(), {})
        np.testing.assert_array_equal(planner.act(make_observation()), [0.5, 0.0])
    finally:
        planner.close()
    assert "resetting" in (tmp_path / "stderr.txt").read_text()


PEEKING = """
import numpy as np
class Peeking:
    reads_log = {reads_log}
    def reset(self, observation, info):
        self.saw = "logged_ego" in info
    def act(self, observation):
        return np.array([1.0 if self.saw else 0.0, 0.0])
"""


@pytest.mark.parametrize("reads_log", [False, True])
def test_only_a_planner_that_reads_the_log_is_given_it_in_process_and_over_json_lines(tmp_path, reads_log):
    """The ego's logged future is the log-replay baseline's alone: a planner declaring nothing never sees it."""
    (tmp_path / "peeking.py").write_text(PEEKING.format(reads_log=reads_log))
    sys.path.insert(0, str(tmp_path))
    try:
        from peeking import Peeking

        info = {"scenario_id": "s", "ego_id": 1, "step_seconds": 0.1, "logged_ego": np.zeros((80, 4))}
        local = Peeking()
        reset_planner(local, make_observation(), info)
        command = f"env PYTHONPATH={shlex.quote(str(tmp_path))} {SERVE} peeking:Peeking"
        remote = SubprocessPlanner(command, timeout_s=30.0)
        try:
            assert remote.reads_log is reads_log
            reset_planner(remote, make_observation(), info)
            remote_saw = bool(remote.act(make_observation())[0] == 1.0)
        finally:
            remote.close()
    finally:
        sys.path.remove(str(tmp_path))
        sys.modules.pop("peeking", None)
    assert local.saw is reads_log and remote_saw is reads_log
    assert "logged_ego" in info  # the caller's info is left as it was
