"""Bad scenario files given to `inspect`, `render` and `convert`: one line on standard error and no output."""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest
from scenario_builders import make_scenario

from cli.helpers import assert_one_line_error, run_cli
from langtraj.scenario.io.tfrecord import write_records
from langtraj.scenario.io.womd import scenario_to_proto


def _pickle_calling_os_system(marker: Path) -> bytes:
    class Exploit:
        def __reduce__(self):
            import os

            return (os.system, (f"touch {marker}",))

    return pickle.dumps(Exploit(), protocol=4)


@pytest.mark.parametrize("verb", ["inspect", "render", "convert"])
def test_bad_inputs_give_one_line_and_no_output(tmp_path: Path, toy_file: Path, capsys, verb: str) -> None:
    good = toy_file.read_bytes()
    flipped = bytearray(good)
    flipped[200] ^= 0xFF
    nan_msg = scenario_to_proto(make_scenario())
    nan_msg.tracks[2].states[50].center_x = float("nan")
    marker = tmp_path / "pwned"
    cases = {
        "missing.tfrecord": None,
        "truncated.tfrecord": good[: len(good) // 2],
        "crc.tfrecord": bytes(flipped),
        "image.png": b"\x89PNG\r\n\x1a\n" + bytes(100),
        "notes.txt": b"scenario_id,x,y\n1,2,3\n",
        "empty.tfrecord": b"",
        "evil.pkl": _pickle_calling_os_system(marker),
    }
    expected = {
        "missing.tfrecord": "no such file",
        "truncated.tfrecord": "truncated",
        "crc.tfrecord": "checksum mismatch",
        "image.png": "not a scenario file",
        "notes.txt": "not a scenario file",
        "empty.tfrecord": "file is empty",
        "evil.pkl": "os",
    }
    write_records(tmp_path / "nan.tfrecord", [nan_msg.SerializeToString()])
    cases["nan.tfrecord"] = (tmp_path / "nan.tfrecord").read_bytes()
    expected["nan.tfrecord"] = "track 27, step 50: non-finite x"
    for name, data in cases.items():
        path = tmp_path / name
        if data is not None:
            path.write_bytes(data)
        out_file = tmp_path / "out" / f"{name}.mp4"
        args = {
            "inspect": ["inspect", path],
            "render": ["render", path, "--out", out_file, "--no-progress"],
            "convert": ["convert", path, tmp_path / "out" / f"{name}.converted.tfrecord"],
        }[verb]
        code, _, err = run_cli(args, capsys)
        assert_one_line_error(code, err, name, expected[name])
    assert not marker.exists(), "the pickle ran code"
    assert not (tmp_path / "out").exists() or list((tmp_path / "out").iterdir()) == []
