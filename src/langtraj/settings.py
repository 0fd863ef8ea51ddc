"""Configuration dataclasses read from mappings (YAML presets, checkpoints) with one-line errors that name
the section and key (docs/model.md, 'Presets')."""

from __future__ import annotations

from dataclasses import fields
from typing import Any

from langtraj.errors import InputError


def dataclass_kwargs(cls: type, data: Any, where: str) -> dict[str, Any]:
    """`data` as keyword arguments of dataclass `cls` (None: no settings); anything but a mapping of
    known keys raises an InputError located at `where`."""
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise InputError(f"expected a mapping of settings, got {type(data).__name__}", where=where)
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InputError(f"unknown keys {', '.join(unknown)}; known: {', '.join(sorted(known))}", where=where)
    return dict(data)


def require(condition: bool, where: str, message: str) -> None:
    """Raise InputError(message) located at `where` unless `condition` holds."""
    if not condition:
        raise InputError(message, where=where)
