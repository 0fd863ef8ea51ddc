"""File access with the project's error conventions: inputs that raise InputError naming the file, and
atomic outputs (write to a temporary file beside the target, then rename over it).

Inputs may be zstd-compressed (recognised by the frame magic, not the name): `open_input` hands every
reader the decompressed bytes, so compressed and plain files read alike.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any, BinaryIO

import zstandard

from langtraj.errors import InputError

ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
"""The first four bytes of a zstd frame."""

ZSTD_SUFFIX = ".zst"
"""The suffix of compressed files (`shard.tfrecord.zst`); reading goes by content, not by this."""

ZSTD_LEVEL = 3
"""Compression level of written files: synthesized shards come out 8-15x smaller, in ~20 ms per 14 MB."""

MAX_DECOMPRESSED_BYTES = 1 << 32
"""Refuse compressed inputs that expand beyond 4 GiB: a corrupt size field must not exhaust memory."""

_CHUNK = 1 << 16


def _open_file(path: Path) -> io.BufferedReader:
    """`path` opened for binary reading as it is on disk; a missing or unreadable file raises InputError."""
    try:
        return path.open("rb")
    except FileNotFoundError:
        raise InputError("no such file", path=path) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a scenario file", path=path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=path) from None


def _is_zstd(fh: io.BufferedReader) -> bool:
    """Whether the file starts with a zstd frame (peeks, so nothing is consumed)."""
    return fh.peek(len(ZSTD_MAGIC))[: len(ZSTD_MAGIC)] == ZSTD_MAGIC


def _inflate(chunks: Iterable[bytes], path: Path) -> Iterator[bytes]:
    """Decompressed pieces of the zstd frames in `chunks` (the compressed bytes in order); InputError naming
    `path` when the data is corrupt or ends inside a frame."""
    dctx = zstandard.ZstdDecompressor()
    obj = None
    try:
        for chunk in chunks:
            while chunk:
                if obj is None or obj.eof:  # one object per frame, so that a cut inside any frame is seen
                    obj = dctx.decompressobj(read_across_frames=False)
                yield obj.decompress(chunk)
                chunk = obj.unused_data if obj.eof else b""
    except zstandard.ZstdError as exc:
        raise InputError(f"corrupt zstd data: {exc}", path=path) from None
    if obj is None or not obj.eof:
        raise InputError("corrupt zstd data: the file ends inside a frame (truncated?)", path=path)


def _too_large(size: int, path: Path) -> InputError:
    return InputError(f"too large to decompress in memory ({size} bytes, at most {MAX_DECOMPRESSED_BYTES})", path=path)


def _decompress(fh: BinaryIO, path: Path) -> bytes:
    """The whole content of the zstd file open as `fh`: one call for a single frame of declared size (what
    LangTraj writes), frame by frame otherwise."""
    if (size := os.fstat(fh.fileno()).st_size) > MAX_DECOMPRESSED_BYTES:
        raise _too_large(size, path)
    data = fh.read()
    try:
        declared = zstandard.frame_content_size(data)  # -1 when the header does not declare it
    except zstandard.ZstdError:
        declared = -1  # header too short to read: `_inflate` below reports it
    if declared > MAX_DECOMPRESSED_BYTES:
        raise _too_large(declared, path)
    if declared >= 0:
        with contextlib.suppress(zstandard.ZstdError):  # several frames, or corrupt: `_inflate` tells which
            return zstandard.ZstdDecompressor().decompress(data, allow_extra_data=False)
    out = bytearray()
    for piece in _inflate([data], path):
        out += piece
        if len(out) > MAX_DECOMPRESSED_BYTES:
            raise _too_large(len(out), path)
    return bytes(out)


def read_json(path: str | Path, missing: str) -> Any:
    """The JSON document at `path`; a missing file raises InputError(`missing`), an unreadable one names the
    parse error, both naming the file."""
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError(missing, path=path) from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"not JSON: {exc}", path=path) from None


def open_input(path: str | Path) -> BinaryIO:
    """Open an input file for binary reading; a missing or unreadable file raises InputError. A zstd file is
    decompressed whole into a seekable in-memory buffer (corrupt data raises InputError naming it)."""
    path = Path(path)
    fh = _open_file(path)
    if not _is_zstd(fh):
        return fh
    with fh:
        return io.BytesIO(_decompress(fh, path))


def read_head(path: str | Path, n: int) -> bytes:
    """The first `n` bytes of `path`'s content, decompressing only as much of a zstd file as that takes (for
    sniffing a folder of compressed shards cheaply)."""
    path = Path(path)
    with _open_file(path) as fh:
        if not _is_zstd(fh):
            return fh.read(n)
        head = bytearray()
        for piece in _inflate(iter(lambda: fh.read(_CHUNK), b""), path):
            head += piece
            if len(head) >= n:
                break
        return bytes(head[:n])


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; on success rename it to `path`, on any
    error remove it, so `path` is either untouched or complete."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file ordinary permissions
    try:
        yield tmp
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def atomic_open(path: str | Path, mode: str = "wb", *, compress: bool = False) -> Iterator:
    """Open a temporary file for writing that replaces `path` only when the block succeeds.

    With `compress` (binary mode only) what the block writes is collected in memory and becomes one zstd
    frame at `ZSTD_LEVEL`, with the content size in its header (readers size their buffer from it) and a
    checksum; compressing the whole content at once packs synthesized shards 3% tighter than streaming.
    """
    if not compress:
        with atomic_path(path) as tmp, open(tmp, mode) as fh:
            yield fh
        return
    if mode != "wb":
        raise ValueError(f"compressed files are written in mode 'wb', not {mode!r}")
    with atomic_path(path) as tmp:
        raw = io.BytesIO()
        yield raw
        tmp.write_bytes(zstandard.ZstdCompressor(level=ZSTD_LEVEL, write_checksum=True).compress(raw.getbuffer()))
