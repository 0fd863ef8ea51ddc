"""TFRecord framing without TensorFlow: streaming reads with checked CRC32C, and atomic writes.

Each record is: uint64 length (little endian), uint32 masked CRC32C of those 8 bytes, the payload,
uint32 masked CRC32C of the payload. Reading streams one record at a time, so shard size does not
matter; skipping records seeks past payloads without reading them. A zstd-compressed file
(`*.tfrecord.zst`) reads the same way, from memory (`langtraj.fileio.open_input`).

See docs/data.md.
"""

from __future__ import annotations

import os
import struct
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import BinaryIO

import google_crc32c

from langtraj.errors import InputError
from langtraj.fileio import atomic_open, open_input

_MASK_DELTA = 0xA282EAD8
_U64 = struct.Struct("<Q")
_U32 = struct.Struct("<I")
HEADER_BYTES = 12
MAX_RECORD_BYTES = 1 << 31
"""Refuse records above 2 GiB: a corrupt length would otherwise trigger a huge allocation."""


def masked_crc32c(data: bytes) -> int:
    """TFRecord's masked CRC32C: rotate right by 15 bits and add a constant."""
    crc = google_crc32c.value(data)
    return (((crc >> 15) | (crc << 17)) + _MASK_DELTA) & 0xFFFFFFFF


def looks_like_tfrecord(head: bytes) -> bool:
    """True when `head` starts with a TFRecord header whose length checksum is right."""
    if len(head) < HEADER_BYTES:
        return False
    (length_crc,) = _U32.unpack_from(head, 8)
    return masked_crc32c(head[:8]) == length_crc


def _read_header(fh: BinaryIO, path: Path, index: int) -> int | None:
    """Payload length of the next record, or None at a clean end of file."""
    header = fh.read(HEADER_BYTES)
    if not header:
        return None
    where = f"record {index}"
    if len(header) < HEADER_BYTES:
        raise InputError(f"truncated header ({len(header)} of {HEADER_BYTES} bytes)", path=path, where=where)
    (length,) = _U64.unpack_from(header, 0)
    (length_crc,) = _U32.unpack_from(header, 8)
    if masked_crc32c(header[:8]) != length_crc:
        raise InputError("length checksum mismatch (corrupt file or not a TFRecord)", path=path, where=where)
    if length > MAX_RECORD_BYTES:
        raise InputError(f"record length {length} exceeds {MAX_RECORD_BYTES} bytes", path=path, where=where)
    return length


def _size(fh: BinaryIO) -> int:
    """Bytes in `fh` (a file or the in-memory content of a compressed one); leaves it at the start."""
    size = fh.seek(0, os.SEEK_END)
    fh.seek(0)
    return size


def _skip_payload(fh: BinaryIO, length: int, size: int, path: Path, index: int) -> None:
    fh.seek(length + 4, os.SEEK_CUR)
    if fh.tell() > size:
        raise InputError("truncated payload", path=path, where=f"record {index}")


def iter_records(path: str | Path, *, start: int = 0, verify: bool = True) -> Iterator[bytes]:
    """Payloads of the records of `path` from index `start` on, one at a time.

    Records before `start` are skipped by seeking (their length checksums are still checked).
    With `verify`, each payload's CRC32C is checked; any mismatch or truncation raises `InputError`
    naming the file and record index.
    """
    path = Path(path)
    with open_input(path) as fh:
        size = _size(fh)
        index = 0
        while (length := _read_header(fh, path, index)) is not None:
            if index < start:
                _skip_payload(fh, length, size, path, index)
                index += 1
                continue
            where = f"record {index}"
            payload = fh.read(length)
            footer = fh.read(4)
            if len(payload) < length or len(footer) < 4:
                raise InputError(f"truncated payload ({len(payload)} of {length} bytes)", path=path, where=where)
            if verify and masked_crc32c(payload) != _U32.unpack(footer)[0]:
                raise InputError("payload checksum mismatch (corrupt record)", path=path, where=where)
            yield payload
            index += 1


def count_records(path: str | Path) -> int:
    """Number of records, found by seeking over payloads."""
    path = Path(path)
    with open_input(path) as fh:
        size = _size(fh)
        count = 0
        while (length := _read_header(fh, path, count)) is not None:
            _skip_payload(fh, length, size, path, count)
            count += 1
    return count


def encode_record(payload: bytes) -> bytes:
    """One framed record."""
    header = _U64.pack(len(payload))
    return header + _U32.pack(masked_crc32c(header)) + payload + _U32.pack(masked_crc32c(payload))


def write_records(path: str | Path, payloads: Iterable[bytes], *, compress: bool = False) -> int:
    """Write framed records atomically (temporary file, then rename), as one zstd frame with `compress`;
    returns the record count."""
    count = 0
    with atomic_open(path, "wb", compress=compress) as fh:
        for payload in payloads:
            fh.write(encode_record(payload))
            count += 1
    return count
