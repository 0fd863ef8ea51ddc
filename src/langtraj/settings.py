"""Configuration read from YAML files and mappings (training presets, recipes, experiment configs,
checkpoints) into typed dataclasses, with one-line errors that name the file, the section and the key
(docs/model.md, 'Presets'; docs/experiments.md, 'Experiment configs')."""

from __future__ import annotations

import dataclasses
import types
import typing
from dataclasses import MISSING, fields
from pathlib import Path
from typing import Any

import yaml

from langtraj.errors import InputError


def dataclass_kwargs(cls: type, data: Any, where: str) -> dict[str, Any]:
    """`data` as keyword arguments of dataclass `cls` (None: no settings); anything but a mapping of
    known keys raises an InputError located at `where`."""
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise InputError(f"expected a mapping of settings, got {type(data).__name__}", where=where)
    known = {f.name for f in fields(cls) if f.init}
    unknown = sorted(set(data) - known)
    if unknown:
        raise InputError(f"unknown keys {', '.join(unknown)}; known: {', '.join(sorted(known))}", where=where)
    return dict(data)


def require(condition: bool, where: str, message: str) -> None:
    """Raise InputError(message) located at `where` unless `condition` holds."""
    if not condition:
        raise InputError(message, where=where)


def _merge(base: dict[str, Any], top: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in top.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def read_yaml(path: str | Path, _seen: tuple[Path, ...] = ()) -> dict[str, Any]:
    """The YAML mapping at `path` with its `extends: other.yaml` chain (relative to the file) merged in, the
    file's keys overriding the other's section by section."""
    path = Path(path).resolve()
    if path in _seen:
        raise InputError("circular 'extends'", path=path)
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except FileNotFoundError:
        raise InputError("no such file", path=path) from None
    except yaml.YAMLError as exc:
        raise InputError(f"not valid YAML: {exc}", path=path) from None
    if not isinstance(data, dict):
        raise InputError("expected a mapping of settings", path=path)
    parent = data.pop("extends", None)
    if parent is None:
        return data
    return _merge(read_yaml(path.parent / parent, (*_seen, path)), data)


def build_dataclass(cls: type, data: Any, where: str = "") -> Any:
    """An instance of dataclass `cls` from a mapping, its fields converted by their annotations: nested
    dataclasses from mappings (or from strings, for classes with a `parse` shorthand), tuples from lists,
    `Path`s from strings, and numbers, booleans and strings checked. Any mistake is one InputError at `where`
    plus the field (`methods[1].selector`)."""
    kwargs = dataclass_kwargs(cls, data, where or cls.__name__)
    missing = [
        f.name
        for f in fields(cls)
        if f.init and f.name not in kwargs and f.default is MISSING and f.default_factory is MISSING
    ]
    if missing:
        raise InputError(f"missing {', '.join(missing)}", where=where or None)
    hints = typing.get_type_hints(cls)
    for name, value in kwargs.items():
        kwargs[name] = _convert(hints[name], value, f"{where}.{name}" if where else name)
    try:
        return cls(**kwargs)
    except InputError as exc:
        if not where:
            raise
        inner = None if (exc.where or "").startswith("--") else exc.where  # a flag's name means nothing in a file
        raise InputError(exc.detail, path=exc.path, where=", ".join(w for w in (where, inner) if w)) from None


def load_dataclass(cls: type, path: str | Path, data: dict[str, Any] | None = None) -> Any:
    """`build_dataclass` of the YAML file at `path` (its `extends` chain merged; `data`, when given, in place
    of the file's mapping), errors naming the file."""
    mapping = read_yaml(path) if data is None else data
    try:
        return build_dataclass(cls, mapping)
    except InputError as exc:
        raise exc.located(path=path) from None


_SCALARS: dict[type, tuple[str, type | tuple[type, ...]]] = {
    bool: ("true or false", bool),
    int: ("a whole number", int),
    float: ("a number", (int, float)),
    str: ("text", str),
}
"""What a setting of each scalar type accepts, and how an error names it."""


def _convert(hint: Any, value: Any, where: str) -> Any:
    """`value` as the annotation `hint` asks, or an InputError at `where`."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        options = [a for a in args if a is not type(None)]
        errors = []
        for option in options:
            try:
                return _convert(option, value, where)
            except InputError as exc:
                errors.append(exc)
        raise errors[0]
    if hint is Any:
        return value
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise InputError(f"expected a list, got {type(value).__name__}", where=where)
        element = args[0] if args else Any
        return tuple(_convert(element, v, f"{where}[{i}]") for i, v in enumerate(value))
    if dataclasses.is_dataclass(hint):
        if isinstance(value, hint):
            return value
        if isinstance(value, str) and hasattr(hint, "parse"):
            try:
                return hint.parse(value)
            except InputError as exc:
                raise InputError(exc.detail, where=where) from None
        return build_dataclass(hint, value, where)
    if hint is Path:
        if not isinstance(value, str | Path):
            raise InputError(f"expected a path, got {type(value).__name__}", where=where)
        return Path(value)
    if hint in _SCALARS:
        what, accepted = _SCALARS[hint]
        if not isinstance(value, accepted) or (hint is not bool and isinstance(value, bool)):
            raise InputError(f"expected {what}, got {value!r}", where=where)
        return float(value) if hint is float else value
    return value
