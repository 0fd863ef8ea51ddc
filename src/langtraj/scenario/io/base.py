"""Extension point for scenario file formats: a reader/writer interface plus a registry.

A format is one `ScenarioFormat` subclass registered with `@register_format`; `detect_format`
picks the format by sniffing the file's first bytes (decompressed, for a zstd file), so extensions do
not matter, and `expand_scenario_paths` turns the files and folders named on a command line into
scenario files the same way. docs/data.md lists the formats.
"""

from __future__ import annotations

import os
from abc import ABC, abstractmethod
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import ClassVar

from langtraj.errors import InputError
from langtraj.fileio import ZSTD_SUFFIX, read_head
from langtraj.registry import Registry
from langtraj.scenario.model import Scenario

SNIFF_BYTES = 64
"""How many leading bytes `ScenarioFormat.sniff` is shown."""


class ScenarioFormat(ABC):
    """A scenario file format: how to recognise, read and write it.

    `read` streams scenarios one at a time so that large plain files are never loaded whole; it raises
    `InputError` naming the file and record for anything malformed. `write` writes every scenario to
    one file atomically (temporary file, then rename), zstd-compressed with `compress`; reading needs
    nothing for that, as `open_input` decompresses transparently.
    """

    name: ClassVar[str]
    suffixes: ClassVar[tuple[str, ...]] = ()

    @classmethod
    @abstractmethod
    def sniff(cls, head: bytes) -> bool:
        """True when a file starting with `head` (up to SNIFF_BYTES) is in this format."""

    @abstractmethod
    def read(self, path: Path) -> Iterator[Scenario]:
        """Scenarios in `path`, in file order."""

    def read_one(self, path: Path, index: int) -> Scenario:
        """The scenario at position `index` of `path` (formats may skip earlier records cheaply)."""
        count = 0
        for count, scenario in enumerate(self.read(path), start=1):
            if count - 1 == index:
                return scenario
        raise InputError(f"no scenario at index {index}; the file holds {count}", path=path)

    @abstractmethod
    def write(self, path: Path, scenarios: Iterable[Scenario], *, compress: bool = False) -> int:
        """Write `scenarios` to `path` atomically (as one zstd frame with `compress`); returns how many were
        written."""


_FORMATS: Registry[ScenarioFormat] = Registry("scenario format")


def register_format(cls: type[ScenarioFormat]) -> type[ScenarioFormat]:
    """Class decorator adding a format to the registry under `cls.name`."""
    return _FORMATS.register(cls)


def available_formats() -> list[str]:
    return sorted(_FORMATS.names())


def get_format(name: str) -> ScenarioFormat:
    return _FORMATS.create(name)


def _head(path: Path) -> bytes:
    """The first SNIFF_BYTES of `path`'s content (of a zstd file, decompressed); a missing or unreadable
    file raises InputError."""
    return read_head(path, SNIFF_BYTES)


def _format_of(head: bytes) -> type[ScenarioFormat] | None:
    """The registered format whose `sniff` accepts `head`; None for an empty head or no known format."""
    return next((cls for cls in _FORMATS.classes() if cls.sniff(head)), None) if head else None


def detect_format(path: str | Path) -> ScenarioFormat:
    """The registered format whose `sniff` accepts the file's first bytes."""
    path = Path(path)
    head = _head(path)
    if not head:
        raise InputError("file is empty", path=path)
    cls = _format_of(head)
    if cls is None:
        raise InputError(f"not a scenario file (known formats: {', '.join(available_formats())})", path=path)
    return cls()


def _unreadable_folder(exc: OSError) -> None:
    raise InputError(f"cannot read folder: {exc.strerror}", path=exc.filename)


def expand_scenario_paths(paths: Iterable[str | Path]) -> list[Path]:
    """The scenario files that command-line `paths` name: each file as given, and in its place every
    scenario file under each folder, searched recursively in sorted order of relative path.

    In a folder, files are recognised by content (`sniff`, as `detect_format` does); other files (a
    README, a manifest, an empty file) are skipped, and so are hidden files and folders (such as the
    temporary files of an unfinished write), links to folders, broken links, pipes and sockets. A
    folder with no scenario file raises InputError naming it. A path that is not a folder is kept as
    it is, so that reading it reports a missing file or another format as before.
    """
    out: list[Path] = []
    for path in map(Path, paths):
        if not path.is_dir():
            out.append(path)
            continue
        found = []
        for folder, subfolders, files in os.walk(path, onerror=_unreadable_folder):
            subfolders[:] = [d for d in subfolders if not d.startswith(".")]
            found.extend(Path(folder, f) for f in files if not f.startswith("."))
        found = [
            f for f in sorted(found, key=lambda f: f.relative_to(path).parts) if f.is_file() and _format_of(_head(f))
        ]
        if not found:
            raise InputError(
                f"no scenario file in this folder or its subfolders (known formats: {', '.join(available_formats())})",
                path=path,
            )
        out.extend(found)
    return out


def format_for_output(path: str | Path, name: str | None = None) -> ScenarioFormat:
    """The format to write `path` in: `name` if given, else the one whose suffixes match the path (before a
    compression suffix: `shard.tfrecord.zst` is WOMD)."""
    if name:
        return get_format(name)
    path_str = str(path).lower().removesuffix(ZSTD_SUFFIX)
    for cls in _FORMATS.classes():
        if any(path_str.endswith(s) for s in cls.suffixes):
            return cls()
    raise InputError(
        "cannot tell the output format from the file name; use a suffix "
        + ", ".join(s for c in _FORMATS.classes() for s in c.suffixes)
        + f" (then {ZSTD_SUFFIX} to compress)",
        path=path,
    )
