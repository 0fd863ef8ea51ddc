"""Running a training stage: seeding, model initialisation, loggers, checkpoints, resume.

Checkpoints go to `RUN_DIR/checkpoints/` every `checkpoint_every_steps` steps (`last.ckpt` plus the two
most recent numbered ones), each written to a temporary file and renamed, so a kill loses at most the
steps since the last checkpoint and never leaves a half-written file. Logs: TensorBoard and CSV under
`RUN_DIR/logs/`.

See docs/model.md.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytorch_lightning as pl
import torch
from pytorch_lightning.callbacks import LearningRateMonitor, ModelCheckpoint
from pytorch_lightning.loggers import CSVLogger, TensorBoardLogger
from pytorch_lightning.plugins.io import TorchCheckpointIO

from langtraj.model.checkpoint import read_checkpoint
from langtraj.training.config import TrainConfig
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


def _initialise(module: LangTrajModule, path: str) -> None:
    """Stage 2 starts from stage 1's weights; the new text branch keeps its fresh initialisation."""
    checkpoint = read_checkpoint(path)
    own = module.state_dict()
    state = {k: v for k, v in checkpoint["state_dict"].items() if k in own and own[k].shape == v.shape}
    module.load_state_dict(state, strict=False)


def resolve_resume(resume: str | None, out: Path) -> str | None:
    """`auto`: the run's `last.ckpt` when there is one; a path: that file; None: a fresh start."""
    if resume is None:
        return None
    if resume == "auto":
        last = out / "checkpoints" / "last.ckpt"
        return str(last) if last.is_file() else None
    read_checkpoint(resume)  # fail early with a clear message
    return resume


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
    module = LangTrajModule(config.to_dict())
    ckpt_path = resolve_resume(resume, out)
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
        callbacks=[checkpoints, LearningRateMonitor(logging_interval="step")],
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
