"""TFRecord framing: round trip, checksum verification, truncation, skipping."""

from __future__ import annotations

from pathlib import Path

import pytest

from langtraj.errors import InputError
from langtraj.scenario.io.tfrecord import (
    count_records,
    encode_record,
    iter_records,
    looks_like_tfrecord,
    masked_crc32c,
    write_records,
)

PAYLOADS = [b"first", b"", b"x" * 1000, bytes(range(256))]


@pytest.fixture
def shard(tmp_path: Path) -> Path:
    path = tmp_path / "shard.tfrecord"
    assert write_records(path, PAYLOADS) == len(PAYLOADS)
    return path


def test_masked_crc_of_the_crc32c_check_string() -> None:
    # CRC32C("123456789") is the standard check value 0xE3069283; rotated right 15 and offset by
    # TensorFlow's mask delta 0xA282EAD8 it gives 0xC78AB0E5.
    assert masked_crc32c(b"123456789") == 0xC78AB0E5
    assert encode_record(b"a")[-4:] == masked_crc32c(b"a").to_bytes(4, "little")


def test_reads_a_file_written_by_tensorflow(real_data_dir: Path) -> None:
    (payload,) = iter_records(real_data_dir / "motion_data_one_scenario.tfrecord")
    assert len(payload) == 952_947


def test_round_trip_and_count(shard: Path) -> None:
    assert list(iter_records(shard)) == PAYLOADS
    assert count_records(shard) == len(PAYLOADS)
    assert list(iter_records(shard, start=2)) == PAYLOADS[2:]
    assert looks_like_tfrecord(shard.read_bytes()[:12])
    assert not looks_like_tfrecord(b"\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR")


def test_payload_checksum_mismatch_names_record(shard: Path) -> None:
    data = bytearray(shard.read_bytes())
    offset = sum(len(encode_record(p)) for p in PAYLOADS[:2]) + 12 + 10  # inside record 2's payload
    data[offset] ^= 0xFF
    shard.write_bytes(bytes(data))
    records = iter_records(shard)
    assert next(records) == PAYLOADS[0]  # earlier records stream out before the bad one is reached
    with pytest.raises(InputError, match=r"shard.tfrecord: record 2: payload checksum mismatch"):
        list(records)


def test_length_checksum_mismatch(shard: Path) -> None:
    data = bytearray(shard.read_bytes())
    data[0] ^= 0x01
    shard.write_bytes(bytes(data))
    with pytest.raises(InputError, match="record 0: length checksum mismatch"):
        list(iter_records(shard))


@pytest.mark.parametrize("cut", [5, 20, -3])
def test_truncated_file(shard: Path, cut: int) -> None:
    data = shard.read_bytes()
    end = cut if cut > 0 else len(data) + cut
    shard.write_bytes(data[:end])
    with pytest.raises(InputError, match="truncated"):
        list(iter_records(shard))


def test_truncation_found_when_skipping(shard: Path) -> None:
    shard.write_bytes(shard.read_bytes()[:-3])
    with pytest.raises(InputError, match="record 3: truncated"):
        count_records(shard)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no such file"):
        list(iter_records(tmp_path / "absent.tfrecord"))


def test_failed_write_leaves_nothing(tmp_path: Path) -> None:
    def payloads():
        yield b"ok"
        raise RuntimeError("generator failed")

    target = tmp_path / "out.tfrecord"
    with pytest.raises(RuntimeError):
        write_records(target, payloads())
    assert list(tmp_path.iterdir()) == []
