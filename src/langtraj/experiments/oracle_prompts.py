"""Oracle prompts: a check of the text pathway, apart from what the InterDrive labels can tell.

Every agent with a logged future gets one sentence stating where it ends up, in its own frame at
the current step, to `bin_m` metres ("the target agent moves about 35 meters forward and 5 meters to
the left"). Such a sentence says far more about the future than any label does, so a stage-2 run on
a dataset rewritten this way shows whether the model can learn to follow text at all: if its
prompted agents' minADE does not fall well below the no-text figure, the text branch or its training
is at fault; if it does, a small gain on the real prompts comes from what those prompts say.

    langtraj experiment oracle-prompts LABELS_DIR --out ORACLE_DIR [--bin 5]

The rewritten dataset points at the same scenario files; it keeps labels and drops the prompt pools.

See docs/model.md.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from langtraj.errors import InputError
from langtraj.frames import points_to_frame
from langtraj.interdrive.dataset import (
    PromptEntry,
    WindowRecord,
    iter_records,
    load_window,
    read_manifest,
    write_manifest,
    write_shard,
)
from langtraj.interdrive.prompts.compose import TARGET
from langtraj.scenario.model import Scenario
from langtraj.scenario.types import StateField

ORACLE_KEY = "oracle_displacement"
"""The label key an oracle prompt carries (it is not an InterDrive label)."""


def displacement_phrase(forward: float, left: float, bin_m: float) -> str:
    """'moves about F meters forward[ and L meters to the left|right]', each rounded to `bin_m`."""
    f = int(round(forward / bin_m) * bin_m)
    lat = int(round(left / bin_m) * bin_m)
    phrase = f"moves about {f} meters forward"
    if lat:
        phrase += f" and {abs(lat)} meters to the {'left' if lat > 0 else 'right'}"
    return phrase


def oracle_prompts(scenario: Scenario, bin_m: float = 5.0) -> tuple[PromptEntry, ...]:
    """One prompt per agent valid at the current step with a valid future step: its displacement from
    the current step to its last valid one, in its current frame."""
    if bin_m <= 0:
        raise InputError(f"bin must be positive, got {bin_m}")
    agents, c = scenario.agents, scenario.current_index
    prompts = []
    for row, track in enumerate(agents.ids.tolist()):
        future = np.flatnonzero(agents.valid[row, c + 1 :])
        if not agents.valid[row, c] or not len(future):
            continue
        start, end = agents.states[row, c], agents.states[row, c + 1 + future[-1]]
        frame = (float(start[StateField.X]), float(start[StateField.Y]), float(start[StateField.HEADING]))
        forward, left = points_to_frame(end[StateField.X : StateField.Y + 1], frame)
        phrase = displacement_phrase(float(forward), float(left), bin_m)
        prompts.append(
            PromptEntry(f"@{track} {phrase}", (track,), {track: f"{TARGET} {phrase}"}, None, (ORACLE_KEY,), "oracle")
        )
    return tuple(prompts)


def oracle_record(record: WindowRecord, bin_m: float = 5.0) -> WindowRecord:
    """The record with its prompt pool replaced by `oracle_prompts` of its window."""
    return replace(record, prompts=oracle_prompts(load_window(record), bin_m))


def write_oracle_dataset(labels_dir: Path, out: Path, bin_m: float = 5.0) -> int:
    """Rewrite every shard of `labels_dir` into `out` with oracle prompts; returns the window count.
    Shards and manifest are written atomically; `out` must not be `labels_dir`."""
    labels_dir, out = Path(labels_dir), Path(out)
    if out.resolve() == labels_dir.resolve():
        raise InputError("the oracle dataset must go to another folder", path=out)
    manifest = read_manifest(labels_dir)
    count = 0
    for shard, records in iter_records(labels_dir):
        target = out / shard.relative_to(labels_dir)
        target.parent.mkdir(parents=True, exist_ok=True)
        write_shard(target, [oracle_record(r, bin_m) for r in records])
        count += len(records)
    write_manifest(out, {**manifest, "oracle_prompts": {"bin_m": bin_m}})
    return count
