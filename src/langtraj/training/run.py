"""Running a training stage: seeding, model initialisation, loggers, checkpoints, resume.

Checkpoints go to `RUN_DIR/checkpoints/` every `checkpoint_every_steps` steps (`last.ckpt` plus the two
most recent numbered ones), each written to a temporary file and renamed, so a kill loses at most the
steps since the last checkpoint and never leaves a half-written file. Logs: TensorBoard and CSV under
`RUN_DIR/logs/`.

See docs/model.md.
"""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytorch_lightning as pl
import torch
from pytorch_lightning.callbacks import LearningRateMonitor, ModelCheckpoint
from pytorch_lightning.loggers import CSVLogger, TensorBoardLogger
from pytorch_lightning.plugins.io import TorchCheckpointIO
from pytorch_lightning.utilities import rank_zero_only

from langtraj.fileio import atomic_path
from langtraj.model.checkpoint import read_checkpoint
from langtraj.training.config import TrainConfig
from langtraj.training.data import SceneDataset, dataset_map_coverage
from langtraj.training.module import CorpusData, LangTrajModule


class AtomicCheckpointIO(TorchCheckpointIO):
    """Checkpoints written to a hidden `.partial` file beside the target, then renamed over it: a kill
    mid-write leaves no file that `RUN_DIR/**/*.ckpt` would match."""

    def save_checkpoint(self, checkpoint: dict[str, Any], path, storage_options=None) -> None:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f".{path.name}.partial")
        try:
            torch.save(checkpoint, partial)
            os.replace(partial, path)
        finally:
            partial.unlink(missing_ok=True)


def _leading_slice(saved: torch.Tensor, shape: torch.Size) -> torch.Tensor | None:
    """`saved` cut to `shape` when that keeps its leading entries along the one axis that shrinks (a
    shorter action horizon keeps the weights of the first actions, which the flattened (action, channel)
    layout stores first); None otherwise."""
    if saved.dim() != len(shape):
        return None
    shrunk = [i for i, (old, new) in enumerate(zip(saved.shape, shape, strict=True)) if old != new]
    if len(shrunk) != 1 or saved.shape[shrunk[0]] < shape[shrunk[0]]:
        return None
    return saved.narrow(shrunk[0], 0, shape[shrunk[0]]).clone()


def _initialise(module: LangTrajModule, path: str) -> None:
    """A stage starts from the weights of the one before: stage 2 from stage 1 (the new text branch keeps
    its fresh initialisation), distillation and closed-loop training from the stage before them. A
    shorter horizon (the closed-loop model's 8 actions after 16) keeps the first actions' weights of the
    action embedding and output layers (`_leading_slice`)."""
    checkpoint = read_checkpoint(path)
    own = module.state_dict()
    state = {}
    for key, value in checkpoint["state_dict"].items():
        if key not in own:
            continue
        if own[key].shape == value.shape:
            state[key] = value
        elif (cut := _leading_slice(value, own[key].shape)) is not None:
            state[key] = cut
    module.load_state_dict(state, strict=False)


@rank_zero_only
def report_map_coverage(dataset: SceneDataset, config: TrainConfig, out: Path) -> dict[str, float | int]:
    """Print and write `RUN_DIR/map_coverage.json`: how many agents of `dataset` (the training windows) see
    a lane within 5 m of them in their sample's map now and at their logged 8-s position (docs/model.md,
    'Inputs'). Only the samples' features are read, never their augmentation."""
    coverage = dataset_map_coverage(dataset)
    print(
        f"map coverage ({config.data.map_selection}, {config.data.max_polylines} pieces) on {coverage['agents']} "
        f"agents of {coverage['windows']} training windows: {coverage['now']:.1%} have a lane within 5 m now, "
        f"{coverage['at_8s']:.1%} at their 8-s position"
    )
    out.mkdir(parents=True, exist_ok=True)
    with atomic_path(out / "map_coverage.json") as tmp:
        tmp.write_text(json.dumps(coverage, indent=2))
    return coverage


def _milestones(config: TrainConfig, out: Path) -> list[ModelCheckpoint]:
    """The checkpoints kept every `keep_every_steps` steps, in RUN_DIR/checkpoints/kept/ (none when unset)."""
    if config.keep_every_steps is None:
        return []
    return [
        ModelCheckpoint(
            dirpath=out / "checkpoints" / "kept",
            filename="step{step:07d}",
            auto_insert_metric_name=False,
            every_n_train_steps=config.keep_every_steps,
            save_top_k=-1,
        )
    ]


@rank_zero_only
def _say(text: str) -> None:
    print(text, flush=True)


def resolve_resume(resume: str | None, out: Path) -> tuple[str | None, int | str | None]:
    """The checkpoint to resume from and its `global_step` ("?" when it holds none). `auto`: the run's
    `last.ckpt` when there is one; a path: that file; None: a fresh start (None, None).

    The file is read once, on rank zero only, before training starts (an unreadable one fails there with a
    clear message, before `Trainer.fit` starts the other processes); the other ranks leave it to
    `Trainer.fit` (their step is None)."""
    if resume is None:
        return None, None
    if resume == "auto":
        last = out / "checkpoints" / "last.ckpt"
        if not last.is_file():
            return None, None
        resume = str(last)
    if rank_zero_only.rank != 0:
        return resume, None
    return resume, read_checkpoint(resume).get("global_step", "?")


def train(
    config: TrainConfig,
    data_dir: str | Path,
    out: str | Path,
    *,
    resume: str | None = None,
    max_steps: int | None = None,
    progress: bool = True,
) -> Path:
    """Run one training stage; returns the path of the last checkpoint."""
    out = Path(out)
    if max_steps is not None:
        config = replace(config, max_steps=max_steps)
    pl.seed_everything(config.seed, workers=True, verbose=False)
    data = CorpusData(data_dir, config)
    store = data.train_set.store
    _say(f"input: feature store {store.path}" if store else "input: decoding every window (no feature store for "
         "these sample settings; langtraj features build makes one)")  # fmt: skip
    report_map_coverage(data.train_set, config, out)
    module = LangTrajModule(config.to_dict())
    ckpt_path, step = resolve_resume(resume, out)
    if ckpt_path is not None:
        _say(f"resuming from {ckpt_path} (step {step})")
    if ckpt_path is None and config.init_from:
        _initialise(module, config.init_from)
    checkpoints = ModelCheckpoint(
        dirpath=out / "checkpoints",
        filename="step{step:07d}",
        auto_insert_metric_name=False,
        every_n_train_steps=config.checkpoint_every_steps,
        save_last=True,
        save_top_k=2,
        monitor="step",
        mode="max",
    )
    trainer = pl.Trainer(
        default_root_dir=out,
        max_steps=config.max_steps,
        val_check_interval=config.val_every_steps,
        check_val_every_n_epoch=None,
        num_sanity_val_steps=0,
        logger=[TensorBoardLogger(out / "logs", name="tb"), CSVLogger(out / "logs", name="csv")],
        callbacks=[checkpoints, *_milestones(config, out), LearningRateMonitor(logging_interval="step")],
        plugins=[AtomicCheckpointIO()],
        gradient_clip_val=config.optim.grad_clip,
        accelerator=config.accelerator,
        devices=config.devices,
        num_nodes=config.num_nodes,
        strategy=config.strategy,
        use_distributed_sampler=False,  # CorpusData shares its own stream out among the processes
        precision=config.precision,
        enable_progress_bar=progress,
        log_every_n_steps=max(1, min(10, config.max_steps)),
        deterministic=False,
    )
    trainer.fit(module, datamodule=data, ckpt_path=ckpt_path)
    last = out / "checkpoints" / "last.ckpt"
    # The end state, also when max_steps is not a multiple of the interval (a full checkpoint: it resumes).
    trainer.save_checkpoint(last, weights_only=False)
    return last
