"""The JSON-lines protocol for planners in another process, in any language (docs/testing.md, 'Planners in
another process').

The runner starts the planner's command (split like a shell would, no shell) with pipes for stdin and stdout; the
planner's stderr is passed through (or written to a file) and its last line quoted in errors. Each message is one
JSON object on one line, UTF-8, ending in a newline; the planner answers each message with exactly one line and
writes nothing else to stdout (logs go to stderr):

    runner -> planner                                        planner -> runner
    {"type": "hello", "protocol": 1}                         {"action_kind": "control", "reads_log": false}
    {"type": "reset", "observation": OBS, "info": INFO}      {}                             (any object)
    {"type": "act", "observation": OBS}                      {"action": [a, yaw_rate]}      (or [[x, y, heading], ...])
    {"type": "close"}                                        (no answer: the planner exits)

Hello once after the start; reset at the start of each episode, then one act per 0.1 s step; close at the end.
The hello's reply: `action_kind` "control" (default) or "trajectory"; `reads_log` true only for a log-replay
baseline (default false), which alone gets `logged_ego` in INFO. OBS is the observation
(`langtraj.env.spaces.observation_space`) with each key's array as nested lists of numbers (`encode_observation`);
INFO is the reset info as JSON (`scenario_id`, `ego_id`, `step_seconds`, ...; `logged_ego` as [80][4] lists); a NaN
or infinity anywhere is null. An action is nested lists of the shape of its action space: control [2]
(acceleration, yaw rate), trajectory [10][3] poses. A reply that is not one JSON object, an act reply without a
well-shaped "action", or a planner that exits raises `PlannerError`; no reply within the time limit raises
`PlannerTimeout`. `serve` is the planner side, for any Python planner (`python -m langtraj.planners.serve`).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import selectors
import shlex
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO, Any

import numpy as np

from langtraj.env.spaces import ACTION_KINDS, ActionError, checked_action, observation_space
from langtraj.planners.base import (
    DEFAULT_STEP_TIMEOUT_S,
    Planner,
    PlannerError,
    PlannerTimeout,
    planner_action_kind,
    planner_reads_log,
    reset_planner,
)

PROTOCOL = 1
"""The protocol version the hello carries."""
CLOSE_WAIT_S = 2.0
"""How long `SubprocessPlanner.close` waits for the planner to exit before killing it."""
_READ_BYTES = 1 << 16


def _json_ready(value: Any) -> Any:
    """`value` with numpy arrays and scalars as Python lists and numbers and non-finite floats as None."""
    if isinstance(value, np.ndarray | np.generic):
        value = value.tolist()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(key): _json_ready(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_json_ready(item) for item in value]
    return value


def encode_observation(observation: dict[str, Any]) -> dict[str, Any]:
    """An observation as JSON-ready nested lists (NaN and infinities as None)."""
    encoded = {}
    for key, value in observation.items():
        array = np.asarray(value)
        if array.dtype.kind == "f" and not np.isfinite(array).all():
            encoded[key] = _json_ready(array)
        else:
            encoded[key] = array.tolist()
    return encoded


def decode_observation(data: dict[str, Any]) -> dict[str, np.ndarray]:
    """Nested lists back to the observation's arrays, each of its space's dtype (None as NaN); keys the space does
    not know are kept as float64 arrays."""
    spaces = observation_space().spaces
    decoded = {}
    for key, value in data.items():
        space = spaces.get(key)
        dtype = space.dtype if space is not None and space.dtype is not None else np.float64
        if np.dtype(dtype).kind == "f":
            decoded[key] = np.array(value, dtype=np.float64).astype(dtype)  # None -> NaN
        else:
            decoded[key] = np.asarray(value, dtype=dtype)
    return decoded


def encode_info(info: dict[str, Any]) -> dict[str, Any]:
    """The reset info as JSON-ready values (arrays as lists, NaN as None)."""
    return _json_ready(dict(info))


def decode_info(data: dict[str, Any]) -> dict[str, Any]:
    """The reset info as a planner gets it in process: `logged_ego` a float64 array (None as NaN)."""
    info = dict(data)
    if info.get("logged_ego") is not None:
        info["logged_ego"] = np.array(info["logged_ego"], dtype=np.float64).reshape(-1, 4)
    return info


class _StderrTail:
    """Copies a process's stderr to `sink` line by line in a thread, keeping the last non-empty line for errors."""

    def __init__(self, stream: IO[bytes], sink: IO[str]):
        self.last = ""
        self.lines = 0
        self._changed = threading.Condition()
        reader = io.BufferedReader(stream)  # type: ignore[arg-type]  # a raw pipe: read it by lines
        self._thread = threading.Thread(target=self._copy, args=(reader, sink), daemon=True)
        self._thread.start()

    def _copy(self, stream: IO[bytes], sink: IO[str]) -> None:
        for raw in iter(stream.readline, b""):
            line = raw.decode("utf-8", "replace")
            with contextlib.suppress(ValueError, OSError):  # the sink may be closed at exit
                sink.write(line)
                sink.flush()
            with self._changed:
                self.lines += 1
                if line.strip():
                    self.last = line.strip()
                self._changed.notify_all()
        stream.close()

    def join(self, timeout: float) -> None:
        self._thread.join(timeout)

    def line(self, quiet_s: float = 0.1, limit_s: float = 1.0) -> str:
        """The last non-empty line, once no line has come for `quiet_s` (at most `limit_s`): stderr travels apart
        from stdout, so what the planner wrote before its reply may still be on its way."""
        deadline = time.monotonic() + limit_s
        with self._changed:
            seen = -1
            while seen != self.lines and self._thread.is_alive():
                seen = self.lines
                self._changed.wait(max(0.0, min(quiet_s, deadline - time.monotonic())))
                if time.monotonic() >= deadline:
                    break
            return self.last


class SubprocessPlanner(Planner):
    """A planner in another process, spoken to by the JSON-lines protocol of this module: `command` is started at
    construction and greeted; its `action_kind` is the hello's answer. Each reply may take `timeout_s` (the hello
    `start_timeout_s`, for planners that load a model); stderr goes to `stderr_path` if given, else to ours."""

    name = "subprocess"  # not registered: built from a command, not a name

    def __init__(
        self,
        command: str,
        timeout_s: float = DEFAULT_STEP_TIMEOUT_S,
        *,
        start_timeout_s: float | None = None,
        stderr_path: str | Path | None = None,
    ):
        self.command = command
        self.timeout_s = float(timeout_s)
        argv = shlex.split(command)
        if not argv:
            raise PlannerError("the planner command is empty")
        self._sink: IO[str] = open(stderr_path, "a") if stderr_path is not None else sys.stderr  # noqa: SIM115
        try:
            self._process = subprocess.Popen(
                argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0
            )
        except OSError as error:
            self._close_sink()
            raise PlannerError(f"cannot start planner {command!r}: {error.strerror or error}") from error
        assert self._process.stdin is not None and self._process.stdout is not None
        assert self._process.stderr is not None
        self._stdin, self._stdout = self._process.stdin.fileno(), self._process.stdout.fileno()
        os.set_blocking(self._stdin, False)
        os.set_blocking(self._stdout, False)
        self._buffer = b""
        self._closed = False
        self._broken = ""  # why the conversation cannot go on (a reply missed or malformed)
        self._stderr = _StderrTail(self._process.stderr, self._sink)
        try:
            reply = self._ask({"type": "hello", "protocol": PROTOCOL}, "hello", start_timeout_s or self.timeout_s)
            kind = reply.get("action_kind", "control")
            if kind not in ACTION_KINDS:
                raise self._error(f"answered hello with action_kind {kind!r}, not one of {', '.join(ACTION_KINDS)}")
            reads_log = reply.get("reads_log", False)
            if not isinstance(reads_log, bool):
                raise self._error(f"answered hello with reads_log {reads_log!r}, not true or false")
        except BaseException:
            self._broken = self._broken or "failed its hello"
            self.close()
            raise
        self.action_kind = kind  # type: ignore[misc]  # learned from the planner, per instance
        self.reads_log = reads_log  # type: ignore[misc]

    def reset(self, observation: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        """Sends the reset message and waits for its reply (any object)."""
        message = {"type": "reset", "observation": encode_observation(observation), "info": encode_info(info)}
        self._ask(message, "reset", self.timeout_s)

    def act(self, observation: dict[str, np.ndarray]) -> np.ndarray:
        """Sends the act message; the reply's "action" as a float32 array of the action space's shape."""
        reply = self._ask({"type": "act", "observation": encode_observation(observation)}, "act", self.timeout_s)
        if "action" not in reply:
            raise self._error(f'answered act without "action": {_clip(json.dumps(reply))}')
        try:
            return checked_action(reply["action"], self.action_kind).astype(np.float32)
        except ActionError as error:
            raise self._error(f"answered act with {error}: {_clip(json.dumps(reply))}") from None

    def close(self) -> None:
        """Sends close, waits `CLOSE_WAIT_S` for the planner to exit, then kills it. Safe to call twice."""
        if self._closed:
            return
        self._closed = True
        if not self._broken:  # a planner that missed a reply is not waited for
            with contextlib.suppress(OSError, PlannerError):
                self._send({"type": "close"}, "close", CLOSE_WAIT_S)
        with contextlib.suppress(OSError):
            self._process.stdin.close()  # type: ignore[union-attr]
        try:
            self._process.wait(0.0 if self._broken else CLOSE_WAIT_S)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait()
        with contextlib.suppress(OSError):
            self._process.stdout.close()  # type: ignore[union-attr]
        self._stderr.join(1.0)
        self._close_sink()

    def _close_sink(self) -> None:
        if self._sink is not sys.stderr:
            self._sink.close()

    def __del__(self) -> None:
        if not getattr(self, "_closed", True):
            with contextlib.suppress(Exception):
                self.close()

    def _error(self, reason: str) -> PlannerError:
        last = self._stderr.line() if hasattr(self, "_stderr") else ""
        suffix = f"; its last stderr line: {_clip(last)}" if last else ""
        return PlannerError(f"planner {self.command!r} {reason}{suffix}")

    def _exited(self, doing: str) -> PlannerError:
        try:
            code = self._process.wait(0.5)
        except subprocess.TimeoutExpired:
            return self._error(f"closed its stdout during {doing}")
        self._stderr.join(0.5)  # let the last stderr lines arrive
        return self._error(f"exited (code {code}) during {doing}")

    def _ask(self, message: dict[str, Any], doing: str, timeout_s: float) -> dict[str, Any]:
        """Sends `message` and reads the one-line reply, both within `timeout_s` in all. After an error the
        conversation is out of step: every later message raises PlannerError."""
        if self._closed or self._broken:
            raise PlannerError(f"planner {self.command!r} {'is closed' if self._closed else self._broken}")
        deadline = time.monotonic() + timeout_s
        try:
            self._send(message, doing, timeout_s, deadline)
            line = self._read_line(doing, timeout_s, deadline)
            try:
                reply = json.loads(line)
            except ValueError:
                raise self._error(f"answered {doing} with a line that is not JSON: {_clip(line)}") from None
            if not isinstance(reply, dict):
                raise self._error(f"answered {doing} with JSON that is not an object: {_clip(line)}")
        except PlannerError as error:
            self._broken = f"failed {doing} earlier ({type(error).__name__})"
            raise
        return reply

    def _send(self, message: dict[str, Any], doing: str, timeout_s: float, deadline: float | None = None) -> None:
        data = (json.dumps(message, allow_nan=False, separators=(",", ":")) + "\n").encode()
        deadline = deadline if deadline is not None else time.monotonic() + timeout_s
        with selectors.DefaultSelector() as selector:
            selector.register(self._stdin, selectors.EVENT_WRITE)
            while data:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or not selector.select(remaining):
                    raise PlannerTimeout(
                        f"planner {self.command!r} did not read the {doing} message within {timeout_s:g} s"
                    )
                try:
                    written = os.write(self._stdin, data)
                except BlockingIOError:
                    continue
                except (BrokenPipeError, ConnectionResetError):
                    raise self._exited(doing) from None
                data = data[written:]

    def _read_line(self, doing: str, timeout_s: float, deadline: float) -> str:
        with selectors.DefaultSelector() as selector:
            selector.register(self._stdout, selectors.EVENT_READ)
            while b"\n" not in self._buffer:
                remaining = deadline - time.monotonic()
                if remaining <= 0 or not selector.select(remaining):
                    raise PlannerTimeout(f"planner {self.command!r} did not answer {doing} within {timeout_s:g} s")
                try:
                    chunk = os.read(self._stdout, _READ_BYTES)
                except BlockingIOError:
                    continue
                if not chunk:
                    raise self._exited(doing)
                self._buffer += chunk
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line.decode("utf-8", "replace").strip()


def _clip(text: str, limit: int = 200) -> str:
    """`text` on one line, cut to `limit` characters."""
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 3] + "..."


def serve(planner: Any, stdin: IO[str] | None = None, stdout: IO[str] | None = None) -> None:
    """The planner side of the protocol: answers messages from `stdin` on `stdout` (default: this process's) until
    close or end of input, then closes the planner. Whatever the planner itself prints goes to stderr, so stdout
    carries protocol lines only."""
    stdin = stdin if stdin is not None else sys.stdin
    stdout = stdout if stdout is not None else sys.stdout

    def answer(reply: dict[str, Any]) -> None:
        stdout.write(json.dumps(reply, allow_nan=False, separators=(",", ":")) + "\n")
        stdout.flush()

    try:
        for line in stdin:
            if not line.strip():
                continue
            message = json.loads(line)
            kind = message.get("type")
            with contextlib.redirect_stdout(sys.stderr):
                if kind == "hello":
                    reply: dict[str, Any] = {
                        "action_kind": planner_action_kind(planner),
                        "reads_log": planner_reads_log(planner),
                    }
                elif kind == "reset":
                    reset_planner(planner, decode_observation(message["observation"]), decode_info(message["info"]))
                    reply = {}
                elif kind == "act":
                    action = np.asarray(planner.act(decode_observation(message["observation"])), np.float64)
                    reply = {"action": _json_ready(action)}
                elif kind == "close":
                    return
                else:
                    raise ValueError(f"unknown message type {kind!r}")
            answer(reply)
    finally:
        close = getattr(planner, "close", None)
        if callable(close):
            with contextlib.redirect_stdout(sys.stderr):
                close()
