"""Extension point for scenario file formats: a reader/writer interface plus a registry.

A format is one `ScenarioFormat` subclass registered with `@register_format`; `open_scenarios`
picks the format by sniffing the file's first bytes, so extensions do not matter.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import ClassVar

from langtraj.errors import InputError
from langtraj.fileio import open_input
from langtraj.registry import Registry
from langtraj.scenario.model import Scenario

SNIFF_BYTES = 64
"""How many leading bytes `ScenarioFormat.sniff` is shown."""


class ScenarioFormat(ABC):
    """A scenario file format: how to recognise, read and write it.

    `read` streams scenarios one at a time so that large files are never loaded whole; it raises
    `InputError` naming the file and record for anything malformed. `write` writes every scenario to
    one file atomically (temporary file, then rename).
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
    def write(self, path: Path, scenarios: Iterable[Scenario]) -> int:
        """Write `scenarios` to `path` atomically; returns how many were written."""


_FORMATS: Registry[ScenarioFormat] = Registry("scenario format")


def register_format(cls: type[ScenarioFormat]) -> type[ScenarioFormat]:
    """Class decorator adding a format to the registry under `cls.name`."""
    return _FORMATS.register(cls)


def available_formats() -> list[str]:
    return sorted(_FORMATS.names())


def get_format(name: str) -> ScenarioFormat:
    return _FORMATS.create(name)


def detect_format(path: str | Path) -> ScenarioFormat:
    """The registered format whose `sniff` accepts the file's first bytes."""
    path = Path(path)
    with open_input(path) as fh:
        head = fh.read(SNIFF_BYTES)
    if not head:
        raise InputError("file is empty", path=path)
    for cls in _FORMATS.classes():
        if cls.sniff(head):
            return cls()
    raise InputError(f"not a scenario file (known formats: {', '.join(available_formats())})", path=path)


def format_for_output(path: str | Path, name: str | None = None) -> ScenarioFormat:
    """The format to write `path` in: `name` if given, else the one whose suffixes match the path."""
    if name:
        return get_format(name)
    path_str = str(path).lower()
    for cls in _FORMATS.classes():
        if any(path_str.endswith(s) for s in cls.suffixes):
            return cls()
    raise InputError(
        "cannot tell the output format from the file name; use a suffix "
        + ", ".join(s for c in _FORMATS.classes() for s in c.suffixes),
        path=path,
    )
