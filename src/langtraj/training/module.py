"""Lightning wiring: the training step, validation measures, optimiser schedule, data loading and
checkpoints that resume exactly (weights, optimiser, scheduler, step, data position; randomness
derives from the step). See docs/model.md."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytorch_lightning as pl
import torch
from torch.utils.data import DataLoader, Sampler

from langtraj import __version__
from langtraj.errors import InputError
from langtraj.metrics.wosac import evaluate_scenario
from langtraj.model.checkpoint import CHECKPOINT_FORMAT, restore_frozen, strip_frozen
from langtraj.model.features import collate_scenes
from langtraj.model.langtraj import LangTraj
from langtraj.sim.open_loop import open_loop_rollouts, sample_open_loop
from langtraj.training.closed_loop import closed_loop_loss
from langtraj.training.config import TrainConfig
from langtraj.training.data import MixingSampler, SceneDataset
from langtraj.training.evaluation import constant_velocity, min_ade
from langtraj.training.penalties import scene_penalties
from langtraj.training.perturbation import perturb_pasts

FUSED_DEVICES = frozenset({"cpu", "cuda"})
"""Devices for which torch has a fused AdamW kernel (`make_optimizer`)."""

SCALED_PRECISIONS = frozenset({"16-mixed", "16"})
"""Lightning precisions that scale the loss (a `GradScaler`): gradients are unscaled before clipping, which a
fused optimizer would do only inside its step, so these train with the multi-tensor AdamW (`make_optimizer`)."""


def make_optimizer(
    params: list[torch.nn.Parameter], *, lr: float, weight_decay: float, fused: bool = True
) -> torch.optim.AdamW:
    """AdamW for `params`: fused (one kernel updates every parameter, its step counts kept on the device) when
    asked and the parameters' device has it, else multi-tensor (docs/model.md, 'Fewer, bigger kernels'). On an
    H100 the multi-tensor AdamW of `gpu-short` issued 2,275 operations a step, most of them reading and counting
    per-parameter step counts on the host; the capturable multi-tensor AdamW, tried as a cure, was slower
    (docs/benchmarks.md, 'GPU check')."""
    fused = fused and bool(params) and all(p.device.type in FUSED_DEVICES for p in params)
    return torch.optim.AdamW(params, lr=lr, weight_decay=weight_decay, fused=fused, foreach=None if fused else True)


def is_fused(optimizer: torch.optim.Optimizer) -> bool:
    """Whether `optimizer` runs a fused kernel (as built, or as a loaded checkpoint's state left it)."""
    return any(group.get("fused") for group in optimizer.param_groups)


class LangTrajModule(pl.LightningModule):
    """One training stage of `LangTraj` (stage 1: no text; stage 2: text and LoRA)."""

    def __init__(self, config: dict[str, Any]):
        super().__init__()
        self.train_config = TrainConfig.from_dict(config)
        self.save_hyperparameters({"config": self.train_config.to_dict(), "langtraj_version": __version__})
        self.model = LangTraj(self.train_config.model)
        if self.train_config.compile:  # the training step only: validation samples other shapes, eagerly
            self.model.compile_steps(training=True, sampling=False, mode=self.train_config.compile_mode)
        self._val: dict[str, float] = {}

    # ------------------------------------------------------------------ steps
    def on_train_batch_start(self, batch, batch_idx: int) -> None:
        """Every step's randomness (diffusion step, noise, dropout) derives from (seed, step, process rank)
        alone, so a run resumed from a checkpoint draws exactly what the uninterrupted run would have,
        and DDP processes draw differently from each other."""
        step, rank, world = _position(self.trainer)
        torch.manual_seed(self.train_config.seed * 1_000_003 + step * world + rank)

    def objective(self, batch) -> dict[str, torch.Tensor]:
        """The stage's loss and its parts on one batch (denoising, or Algorithm 1's closed-loop loss)."""
        if self.train_config.objective == "closed_loop":
            config = self.train_config.closed_loop
            out = closed_loop_loss(self.model, batch, config)
            if config.denoising_weight > 0:
                out["denoising"] = self.model.loss(batch, text_weight=self.train_config.text_loss_weight)["loss"]
                out["loss"] = out["loss"] + config.denoising_weight * out["denoising"]
            return out
        batch = perturb_pasts(batch, self.train_config.perturbation)  # recovery training (off by default)
        penalties = self.train_config.penalties  # map- and contact-aware training (off by default)
        out = self.model.loss(batch, text_weight=self.train_config.text_loss_weight, with_states=penalties.active)
        if penalties.active:
            extra = scene_penalties(batch, out.pop("states"), penalties, out.pop("signal"))
            out = {**out, **extra, "loss": out["loss"] + extra["penalty"]}
        return out

    def training_step(self, batch, batch_idx: int) -> torch.Tensor:
        out = self.objective(batch)
        size = batch.batch_size
        for name, value in out.items():
            self.log(f"train/{name}", value, batch_size=size, prog_bar=name in ("loss", "ade"))
        return out["loss"]

    def on_validation_epoch_start(self) -> None:
        self._val = {}

    def _accumulate(self, name: str, total: torch.Tensor, count: torch.Tensor) -> None:
        s, n = self._val.get(name, (0.0, 0.0))
        self._val[name] = (s + float(total), n + float(count))

    def validation_step(self, batch, batch_idx: int) -> None:
        val = self.train_config.val
        if batch_idx >= val.max_batches:
            return
        out = self.model.loss(batch)
        self._accumulate("loss", out["loss"] * batch.batch_size, torch.tensor(batch.batch_size))
        if self.train_config.objective == "closed_loop":  # every agent on its own: no teacher forcing
            config = replace(self.train_config.closed_loop, teacher_forcing=0.0)
            generator = torch.Generator().manual_seed(self.train_config.seed + batch_idx)
            unrolled = closed_loop_loss(self.model, batch, config, generator=generator)
            self._accumulate("closed_loop_ade", unrolled["ade"] * batch.batch_size, torch.tensor(batch.batch_size))
        generator = torch.Generator(device=self.device).manual_seed(self.train_config.seed + batch_idx)
        kwargs = {"steps": val.sample_steps, "generator": generator}
        states, _ = self.model.sample(batch, val.num_samples, **kwargs)
        self._accumulate("minade", *min_ade(states, batch))
        self._accumulate("cv_minade", *min_ade(constant_velocity(batch, states.shape[-2]), batch))
        if self.model.text_encoder is not None:
            prompted = batch.has_text & batch.agent_valid
            self._accumulate("minade_prompted_text", *min_ade(states, batch, prompted))
            generator.manual_seed(self.train_config.seed + batch_idx)
            plain, _ = self.model.sample(batch, val.num_samples, guidance_weight=-1.0, **kwargs)
            self._accumulate("minade_prompted_no_text", *min_ade(plain, batch, prompted))

    def on_validation_epoch_end(self) -> None:
        for name, (total, count) in self._val.items():
            if count:
                self.log(f"val/{name}", total / count, sync_dist=True)
        if self.train_config.val.wosac_scenes and self.trainer is not None and self.trainer.datamodule is not None:
            for name, value in self._wosac(self.trainer.datamodule.val_set).items():
                self.log(f"val/wosac_{name}", value, sync_dist=True)

    def _wosac(self, dataset) -> dict[str, float]:
        """WOSAC metrics of open-loop rollouts (32 by default, no text) on the first validation windows
        that log 80 future steps (`langtraj.metrics`, docs/metrics.md) on what the model samples."""
        val = self.train_config.val
        scores = []
        for index in range(len(dataset)):
            if len(scores) >= val.wosac_scenes:
                break
            scenario = dataset.window(index)
            if not scenario.logs_future():
                continue
            samples = sample_open_loop(
                self.model, scenario, self.train_config.data, num_samples=val.wosac_rollouts,
                steps=val.sample_steps, seed=self.train_config.seed + index,
            )  # fmt: skip
            scores.append(evaluate_scenario(scenario, open_loop_rollouts(scenario, samples)))
        self.model.train()
        if not scores:
            return {}
        keys = ("metametric", "kinematic_metrics", "interactive_metrics", "map_based_metrics")
        return {k: float(np.mean([getattr(s, k) for s in scores])) for k in keys}

    # ------------------------------------------------------------------ optimisation
    def configure_optimizers(self):
        optim = self.train_config.optim
        params = [p for p in self.model.parameters() if p.requires_grad]
        fused = self.train_config.precision not in SCALED_PRECISIONS
        optimizer = make_optimizer(params, lr=optim.lr, weight_decay=optim.weight_decay, fused=fused)
        total = max(self.train_config.max_steps, 1)

        def factor(step: int) -> float:
            if step < optim.warmup_steps:
                return (step + 1) / optim.warmup_steps
            progress = min(1.0, (step - optim.warmup_steps) / max(1, total - optim.warmup_steps))
            return optim.min_lr_ratio + (1 - optim.min_lr_ratio) * 0.5 * (1 + math.cos(math.pi * progress))

        scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, factor)
        return {"optimizer": optimizer, "lr_scheduler": {"scheduler": scheduler, "interval": "step"}}

    def configure_gradient_clipping(self, optimizer, gradient_clip_val=None, gradient_clip_algorithm=None) -> None:
        """Clip a fused optimizer's gradients by norm here: Lightning's own clipping refuses any fused optimizer
        under mixed precision, bf16's too, where no scaler leaves anything to unscale (`SCALED_PRECISIONS` never
        get a fused one). Other optimizers clip through Lightning as before."""
        if not gradient_clip_val:
            return
        if is_fused(optimizer):
            if gradient_clip_algorithm not in (None, "norm"):
                raise InputError(f"gradient clipping {gradient_clip_algorithm!r}: a fused optimizer clips by norm")
            params = [p for group in optimizer.param_groups for p in group["params"]]
            torch.nn.utils.clip_grad_norm_(params, gradient_clip_val)
            return
        super().configure_gradient_clipping(optimizer, gradient_clip_val, gradient_clip_algorithm)

    # ------------------------------------------------------------------ checkpoints
    def on_save_checkpoint(self, checkpoint: dict[str, Any]) -> None:
        """Mark the format and drop the frozen pretrained text weights (they reload from the encoder's
        package), which keeps checkpoints small (`langtraj.model.checkpoint`)."""
        checkpoint["langtraj_format"] = CHECKPOINT_FORMAT
        strip_frozen(checkpoint["state_dict"])

    def on_load_checkpoint(self, checkpoint: dict[str, Any]) -> None:
        if checkpoint.get("langtraj_format") != CHECKPOINT_FORMAT:
            raise InputError(
                f"checkpoint format {checkpoint.get('langtraj_format')!r}, this LangTraj reads {CHECKPOINT_FORMAT}",
                where="checkpoint",
            )
        restore_frozen(checkpoint["state_dict"], self.state_dict())


class RankShare(Sampler[int]):
    """One process's share of an infinite index stream cut into batches of `batch_size`: of every
    `world` consecutive batches it takes the `rank`-th, after dropping the first `skip_steps` * `world`
    batches (the steps already trained). With one process this is the stream itself, resumed; under
    DDP the processes see disjoint batches whose union is the single-process stream, so a run resumes
    exactly on the same number of processes."""

    def __init__(self, sampler: Sampler[int], batch_size: int, *, rank: int = 0, world: int = 1, skip_steps: int = 0):
        if batch_size < 1 or world < 1 or not 0 <= rank < world or skip_steps < 0:
            raise ValueError(f"bad share: batch_size {batch_size}, rank {rank} of {world}, skip_steps {skip_steps}")
        self.sampler, self.batch_size, self.rank, self.world, self.skip = sampler, batch_size, rank, world, skip_steps

    def __iter__(self) -> Iterator[int]:
        start = self.skip * self.world * self.batch_size
        for position, index in enumerate(itertools.islice(iter(self.sampler), start, None)):
            if (position // self.batch_size) % self.world == self.rank:
                yield index


class CorpusData(pl.LightningDataModule):
    """Training and validation windows of an InterDrive dataset folder (labels over scenario files)."""

    def __init__(self, labels_dir: str | Path, config: TrainConfig):
        super().__init__()
        self.labels_dir, self.config = Path(labels_dir), config
        data = config.data if config.stage == 2 else replace(config.data, text=False)
        self.train_set = SceneDataset(self.labels_dir, data, split="train", seed=config.seed)
        self.val_set = SceneDataset(self.labels_dir, data, split="val", seed=config.seed)
        if len(self.train_set) == 0:
            raise InputError("no training window (every window fell in the validation split)", path=self.labels_dir)

    def train_dataloader(self) -> DataLoader:
        sampler = MixingSampler(self.train_set, self.config.batch_size, infinite=True, seed=self.config.seed)
        step, rank, world = _position(self.trainer)
        return DataLoader(
            self.train_set,
            batch_size=self.config.batch_size,
            sampler=RankShare(sampler, self.config.batch_size, rank=rank, world=world, skip_steps=step),
            collate_fn=collate_scenes,
            num_workers=self.config.num_workers,
            persistent_workers=self.config.num_workers > 0,
        )

    def val_dataloader(self) -> DataLoader:
        _, rank, world = _position(self.trainer)
        count = min(len(self.val_set), self.config.val.max_batches * self.config.batch_size * world)
        subset = torch.utils.data.Subset(self.val_set, list(range(rank, count, world)))  # each process its share
        return DataLoader(subset, batch_size=self.config.batch_size, collate_fn=collate_scenes)


def _position(trainer: pl.Trainer | None) -> tuple[int, int, int]:
    """(global step, process rank, number of processes) of a run; (0, 0, 1) outside a trainer."""
    if trainer is None:
        return 0, 0, 1
    return trainer.global_step, trainer.global_rank, trainer.world_size
