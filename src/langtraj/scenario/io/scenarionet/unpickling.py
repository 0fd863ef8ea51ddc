"""Safe loading of ScenarioNet pickles: a restricted unpickler admitting numpy arrays and builtin
containers only, and the sniffing of a pickle's first bytes. See docs/data.md.
"""

from __future__ import annotations

import _compat_pickle
import pickle
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from langtraj.errors import InputError
from langtraj.fileio import open_input
from langtraj.scenario.io.tfrecord import looks_like_tfrecord

try:
    from numpy._core import multiarray as _multiarray
    from numpy._core import numeric as _numeric
except ImportError:  # numpy < 2
    from numpy.core import multiarray as _multiarray  # type: ignore[no-redef]
    from numpy.core import numeric as _numeric  # type: ignore[no-redef]

# ---------------------------------------------------------------------------- safe unpickling


def _encode_latin1(text: str, encoding: str = "latin1") -> bytes:
    """`_codecs.encode` as protocol 2 uses it to rebuild bytes; only latin-1 is accepted."""
    if encoding not in ("latin1", "latin-1"):
        raise pickle.UnpicklingError(f"refused _codecs.encode with encoding {encoding!r}")
    return text.encode("latin1")


_ALLOWED_GLOBALS: dict[tuple[str, str], Any] = {
    **{(f"numpy.{core}.multiarray", "_reconstruct"): _multiarray._reconstruct for core in ("core", "_core")},
    **{(f"numpy.{core}.multiarray", "scalar"): _multiarray.scalar for core in ("core", "_core")},
    **{(f"numpy.{core}.numeric", "_frombuffer"): _numeric._frombuffer for core in ("core", "_core")},
    ("numpy", "ndarray"): np.ndarray,
    ("numpy", "dtype"): np.dtype,
    ("_codecs", "encode"): _encode_latin1,
    ("builtins", "set"): set,
    ("builtins", "frozenset"): frozenset,
}
"""Every global a ScenarioNet pickle may name as a callable: what numpy arrays, numpy scalars and
(protocol 2) bytes and sets need to be rebuilt. None of them can import anything or run code of the
file's choosing. `collections.defaultdict` and `collections.OrderedDict` are admitted too, but rebuilt
as plain dicts (see `_RestrictedUnpickler`)."""

_DEFAULT_FACTORIES = frozenset(
    ("builtins", name) for name in ("list", "dict", "int", "float", "str", "tuple", "set", "frozenset")
) | {("collections", "OrderedDict"), ("collections", "defaultdict")}
"""The default factories a `collections.defaultdict` in a ScenarioNet file may name (protocol 2 spells
some the Python 2 way: `__builtin__.long`, `__builtin__.unicode`). Those that are not also in
`_ALLOWED_GLOBALS` resolve to a `_FactoryName` that cannot be called."""


@dataclass(frozen=True)
class _FactoryName:
    """A global admitted only as a defaultdict's default factory: calling it (a pickle REDUCE) is
    refused."""

    name: str
    path: Path

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        raise InputError(
            f"refused to call {self.name} from pickle (admitted only as a defaultdict's default factory)",
            path=self.path,
        )


def _python3_name(module: str, name: str) -> tuple[str, str]:
    """The Python 3 name of a global that protocol 2 spells the Python 2 way (`__builtin__.set`,
    `commands.Popen`), translated as the stock `Unpickler.find_class` does."""
    if (module, name) in _compat_pickle.NAME_MAPPING:
        return _compat_pickle.NAME_MAPPING[(module, name)]
    return _compat_pickle.IMPORT_MAPPING.get(module, module), name


class _RestrictedUnpickler(pickle.Unpickler):
    """An unpickler that resolves only `_ALLOWED_GLOBALS`, the two container classes and the default
    factories; any other global raises InputError.

    ScenarioNet writes some metadata, track and map dicts as `collections.defaultdict` or
    `collections.OrderedDict`. Both are rebuilt as plain dicts (the default factory is checked, then
    dropped), so the reader sees what a file of plain dicts gives and nothing of the file's choosing
    is ever called on a missing key.
    """

    def __init__(self, fh: BinaryIO, path: Path):
        super().__init__(fh)
        self._path = path
        self._resolved: dict[tuple[str, str], Any] = {}
        """Each global resolved so far: the same object every time the file names it."""

    def find_class(self, module: str, name: str) -> Any:
        key = _python3_name(module, name)
        if key not in self._resolved:
            self._resolved[key] = self._resolve(key)
        return self._resolved[key]

    def _resolve(self, key: tuple[str, str]) -> Any:
        if key == ("collections", "OrderedDict"):
            return self._ordered_dict
        if key == ("collections", "defaultdict"):
            return self._defaultdict
        if key in _ALLOWED_GLOBALS:
            return _ALLOWED_GLOBALS[key]
        if key in _DEFAULT_FACTORIES:
            return _FactoryName(".".join(key), self._path)
        raise InputError(
            f"refused to load global {key[0]}.{key[1]} from pickle "
            "(only numpy arrays and builtin containers are allowed)",
            path=self._path,
        )

    @staticmethod
    def _ordered_dict(*args: Any) -> dict:
        """`collections.OrderedDict(...)` as a plain dict (dicts keep insertion order)."""
        return dict(*args)

    def _defaultdict(self, default_factory: Any = None, *args: Any) -> dict:
        """`collections.defaultdict(factory, ...)` as a plain dict, once the factory is found to be one
        of `_DEFAULT_FACTORIES` (or None)."""
        if default_factory is None or any(default_factory is self._resolved.get(k) for k in _DEFAULT_FACTORIES):
            return dict(*args)
        named = (".".join(k) for k, v in self._resolved.items() if v is default_factory)
        what = next(named, f"a {type(default_factory).__name__}")
        raise InputError(
            f"refused collections.defaultdict with default factory {what} from pickle "
            "(only builtin containers and numbers are allowed)",
            path=self._path,
        )


def load_pickle(path: str | Path) -> Any:
    """The object pickled in `path`, loaded with the restricted unpickler (InputError when the file
    names a global other than numpy's array machinery and builtin containers, or is truncated or
    corrupt)."""
    path = Path(path)
    with open_input(path) as fh:
        try:
            return _RestrictedUnpickler(fh, path).load()
        except InputError:
            raise
        except Exception as exc:  # corrupt bytes can fail anywhere in the pickle machine
            raise InputError(f"corrupt or truncated pickle ({type(exc).__name__}: {exc})", path=path) from None


def looks_like_scenarionet(head: bytes) -> bool:
    """True when `head` starts a protocol 2-5 pickle. A TFRecord whose first record is 0x0N80 bytes
    long starts the same way, so a head whose TFRecord length checksum holds is left to that format."""
    return len(head) >= 2 and head[0] == 0x80 and 2 <= head[1] <= 5 and not looks_like_tfrecord(head)
