"""A name -> class registry, the one mechanism behind every extension point (scenario formats,
network kinds, and later dynamics, policies, guidance costs, metrics), and `import_object` for classes named
by `package.module:Name` from outside the project."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any, Generic, TypeVar

from langtraj.errors import InputError, one_line

T = TypeVar("T")


def import_object(spec: str, where: str) -> Any:
    """The object `spec` ("package.module:Name", dots allowed in Name) names; a bad spec, a module that does not
    import (importing runs user code: any error) or a missing name raises one InputError at `where`."""
    module_name, _, name = spec.partition(":")
    if not module_name or not name:
        raise InputError(f"{spec!r} is not package.module:Name", where=where)
    try:
        found: Any = importlib.import_module(module_name)
    except Exception as error:
        reason = one_line(error)
        raise InputError(f"cannot import module {module_name!r} of {spec!r} ({reason})", where=where) from error
    for part in name.split("."):
        if not hasattr(found, part):
            raise InputError(f"module {module_name!r} has no {name!r} (from {spec!r})", where=where)
        found = getattr(found, part)
    return found


class Registry(Generic[T]):
    """Classes registered under their `name` attribute; `what` names the kind of thing in errors.

    `loader`, when given, is called once before the first lookup (e.g. to import the built-in
    implementations, which register themselves on import).
    """

    def __init__(self, what: str, loader: Callable[[], None] | None = None):
        self.what = what
        self._classes: dict[str, type[T]] = {}
        self._loader = loader

    def _load(self) -> None:
        if self._loader is not None:
            loader, self._loader = self._loader, None
            loader()

    def register(self, cls: type[T]) -> type[T]:
        """Class decorator adding `cls` under `cls.name`; a second class under one name is an error."""
        name = cls.name  # type: ignore[attr-defined]
        if name in self._classes and self._classes[name] is not cls:
            raise ValueError(f"{self.what} {name!r} is already registered")
        self._classes[name] = cls
        return cls

    def unregister(self, name: str) -> None:
        """Remove the class registered under `name` (a test's or a plugin's own; unknown names are ignored)."""
        self._classes.pop(name, None)

    def names(self) -> tuple[str, ...]:
        """Registered names, in registration order."""
        self._load()
        return tuple(self._classes)

    def classes(self) -> tuple[type[T], ...]:
        self._load()
        return tuple(self._classes.values())

    def get(self, name: str, where: str | None = None) -> type[T]:
        """The class called `name` (for classes that take parameters); an unknown name raises InputError
        listing the known."""
        self._load()
        try:
            return self._classes[name]
        except KeyError:
            known = ", ".join(self._classes)
            raise InputError(f"unknown {self.what} {name!r}; known: {known}", where=where) from None

    def create(self, name: str, where: str | None = None) -> T:
        """A new instance of the class called `name`; an unknown name raises InputError listing the known."""
        return self.get(name, where)()
