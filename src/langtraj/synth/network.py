"""Network kinds: the extension point that builds one randomized SUMO road network per seed.

A kind writes a `.net.xml` (netconvert from nodes/edges XML, or netgenerate) into a work folder and
says where the interesting places are (junction centres, merge areas, crosswalks), so windows can be
cut around them. Register a new kind with `@register_kind`.

See docs/data.md.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np

from langtraj.errors import InputError
from langtraj.registry import Registry


@dataclass(frozen=True)
class InterestCentre:
    """A place where agents interact: windows are cut around it.

    `label` is one of "junction", "merge", "crosswalk"; `junction_id` names the SUMO junction (node)
    when there is one.
    """

    x: float
    y: float
    radius: float
    label: str
    junction_id: str = ""


@dataclass(frozen=True)
class BuiltNetwork:
    """A network written by a kind, with what demand generation and window cutting need.

    `params` records the randomized parameters drawn for this seed (JSON-compatible; kept in each
    window's metadata). `pedestrians` / `bicycles` say whether the network has sidewalks and crossings /
    bike lanes, so demand adds persons / cyclists.
    """

    kind: str
    net_file: Path
    centres: tuple[InterestCentre, ...]
    params: Mapping[str, object] = field(default_factory=dict)
    pedestrians: bool = False
    bicycles: bool = False
    additional_files: tuple[Path, ...] = ()


class NetworkKind(ABC):
    """One family of road networks, randomized by a numpy Generator."""

    name: ClassVar[str]
    description: ClassVar[str]

    @abstractmethod
    def build(self, rng: np.random.Generator, workdir: Path) -> BuiltNetwork:
        """Draw parameters from `rng`, write the network into `workdir`, return what was built."""


def _load_builtin_kinds() -> None:
    from langtraj.synth import kinds  # noqa: F401  (registers the built-in kinds on import)


_KINDS: Registry[NetworkKind] = Registry("scenario kind", loader=_load_builtin_kinds)


def register_kind(cls: type[NetworkKind]) -> type[NetworkKind]:
    """Class decorator adding a kind to the registry under `cls.name`."""
    return _KINDS.register(cls)


def kind_names() -> tuple[str, ...]:
    """Registered kind names, in registration order."""
    return _KINDS.names()


def get_kind(name: str) -> NetworkKind:
    """A new instance of the kind called `name`; an unknown name raises InputError listing the known."""
    return _KINDS.create(name, where="--kinds")


def parse_kinds(spec: str) -> tuple[str, ...]:
    """`"all"` or a comma-separated list of kind names, validated and de-duplicated in order."""
    names = kind_names()
    if spec.strip() == "all":
        return names
    chosen = tuple(dict.fromkeys(s.strip() for s in spec.split(",") if s.strip()))
    if not chosen:
        raise InputError("no scenario kind given", where="--kinds")
    for name in chosen:
        get_kind(name)
    return chosen
