"""The rollout container: R joint simulations of A agents over the 80 future steps, saved as `.npz`.

File layout (the WOSAC reference layout): `object_id` (A,) int64 and `x`, `y`, `z`, `heading`, each
(R, A, T) float32, with T = 80 steps at 10 Hz after the scenario's current step. An optional
`scenario_id` string names the scene the rollouts belong to, so a mismatch can be caught. An optional
`log_following_ids` (int64) lists the agents whose rollouts replay the logged future (log replay, or a
simulation asked to move its undriven agents along the log): such rollouts are a baseline, not a
simulation, and `langtraj submit` refuses them (WOSAC forbids reading the future).

See docs/metrics.md.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from langtraj.errors import InputError
from langtraj.fileio import atomic_path

WOSAC_ROLLOUTS = 32
"""Joint rollouts per scenario in the Waymo Open Sim Agents Challenge."""

_FIELDS = ("x", "y", "z", "heading")


@dataclass(frozen=True, eq=False)
class Rollouts:
    """`x`, `y`, `z`, `heading[r, a, t]`: agent `object_id[a]` at future step `t` of rollout `r`."""

    object_id: np.ndarray  # int64 [A]
    x: np.ndarray  # float32 [R, A, T]
    y: np.ndarray
    z: np.ndarray
    heading: np.ndarray
    scenario_id: str = ""
    log_following_ids: np.ndarray | None = None  # int64 [F]; None: none

    def __post_init__(self) -> None:
        ids = np.asarray(self.object_id)
        if ids.ndim != 1 or not np.issubdtype(ids.dtype, np.integer):
            raise InputError(f"expected a 1-D integer array, got {ids.dtype} {ids.shape}", where="object_id")
        if len(np.unique(ids)) != len(ids):
            raise InputError("repeated object ids", where="object_id")
        object.__setattr__(self, "object_id", ids.astype(np.int64))
        shape = None
        for name in _FIELDS:
            arr = np.asarray(getattr(self, name))
            if arr.ndim != 3:
                raise InputError(f"expected shape (rollouts, agents, steps), got {arr.shape}", where=name)
            if shape is not None and arr.shape != shape:
                raise InputError(f"shape {arr.shape} differs from x's {shape}", where=name)
            shape = arr.shape
            if arr.shape[1] != len(ids):
                raise InputError(f"{arr.shape[1]} agents for {len(ids)} object ids", where=name)
            object.__setattr__(self, name, arr.astype(np.float32, copy=False))
        object.__setattr__(self, "scenario_id", str(self.scenario_id))
        following = np.zeros(0, np.int64) if self.log_following_ids is None else np.asarray(self.log_following_ids)
        following = following.reshape(-1)
        if len(following) and (not np.issubdtype(following.dtype, np.integer) or not np.isin(following, ids).all()):
            raise InputError("must list object ids of these rollouts", where="log_following_ids")
        object.__setattr__(self, "log_following_ids", following.astype(np.int64))

    @property
    def reads_future_log(self) -> bool:
        """Whether some agent's rollouts replay its logged future (not a valid WOSAC simulation)."""
        return bool(len(self.log_following_ids))

    @property
    def num_rollouts(self) -> int:
        return self.x.shape[0]

    @property
    def num_agents(self) -> int:
        return self.x.shape[1]

    @property
    def num_steps(self) -> int:
        return self.x.shape[2]

    def xy(self) -> np.ndarray:
        """Positions as float32 [R, A, T, 2]."""
        return np.stack([self.x, self.y], axis=-1)

    def check_finite(self) -> None:
        """Raise InputError naming the field, rollout, agent and step of the first NaN or inf."""
        for name in _FIELDS:
            bad = ~np.isfinite(getattr(self, name))
            if bad.any():
                r, a, t = (int(v) for v in np.argwhere(bad)[0])
                raise InputError(
                    f"non-finite value at rollout {r}, object {int(self.object_id[a])}, step {t}"
                    f" ({int(bad.sum())} in all)",
                    where=name,
                )

    def save(self, path: str | Path) -> None:
        """Write the `.npz` atomically (uncompressed, as the reference files)."""
        arrays = {"object_id": self.object_id, **{n: getattr(self, n) for n in _FIELDS}}
        if self.scenario_id:
            arrays["scenario_id"] = np.array(self.scenario_id)
        if self.reads_future_log:
            arrays["log_following_ids"] = self.log_following_ids
        with atomic_path(path) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **arrays)

    @classmethod
    def load(cls, path: str | Path) -> Rollouts:
        """Read a rollout `.npz`; a missing, corrupt or malformed file raises InputError naming it."""
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                missing = [n for n in ("object_id", *_FIELDS) if n not in data.files]
                if missing:
                    raise InputError(f"missing arrays {', '.join(missing)} (has {', '.join(data.files)})", path=path)
                arrays = {n: data[n] for n in ("object_id", *_FIELDS)}
                scenario_id = str(data["scenario_id"]) if "scenario_id" in data.files else ""
                if "log_following_ids" in data.files:
                    arrays["log_following_ids"] = data["log_following_ids"]
        except InputError:
            raise
        except FileNotFoundError:
            raise InputError("no such file", path=path) from None
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
            raise InputError(f"not a readable .npz rollout file ({exc})", path=path) from None
        try:
            return cls(scenario_id=scenario_id, **arrays)
        except InputError as exc:
            raise exc.located(path=path) from None
