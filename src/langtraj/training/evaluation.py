"""Open-loop measures used in validation and experiments: minADE over samples, constant velocity, and the
open-loop table of docs/experiments.md."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import torch
from torch import Tensor
from torch.utils.data import DataLoader, Subset

from langtraj.model.batch import SceneBatch
from langtraj.model.config import SampleConfig
from langtraj.model.features import collate_scenes
from langtraj.model.langtraj import LangTraj
from langtraj.rollouts.baselines import BASELINES
from langtraj.scenario.model import STEP_SECONDS
from langtraj.scenario.types import StateField
from langtraj.training.data import SceneDataset


def ade_per_sample(states: Tensor, batch: SceneBatch) -> tuple[Tensor, Tensor]:
    """ADE [S, B, A] of sampled states [S, B, A, T, >=2] against the logged future's first T steps, over valid steps,
    and which agents have any valid future step (bool [B, A])."""
    horizon = states.shape[-2]  # a model may plan fewer than the logged steps (the closed-loop model: 4 s)
    valid = batch.future_valid[..., :horizon] & batch.agent_valid[..., None]
    count = valid.sum(-1)
    err = torch.linalg.norm(states[..., :2] - batch.future[None, :, :, :horizon, :2], dim=-1)
    ade = (err * valid).sum(-1) / count.clamp(min=1)
    return ade, count > 0


def min_ade(states: Tensor, batch: SceneBatch, agents: Tensor | None = None) -> tuple[Tensor, Tensor]:
    """Sum of per-agent minADE over samples and the number of agents counted, for the agents selected by
    `agents` (bool [B, A]; default every agent with a valid future)."""
    ade, has_future = ade_per_sample(states, batch)
    chosen = has_future if agents is None else has_future & agents
    best = ade.min(dim=0).values
    return (best * chosen).sum(), chosen.sum()


def constant_velocity(batch: SceneBatch, steps: int) -> Tensor:
    """States [1, B, A, T, 4] (scene frame) by the WOSAC constant-velocity rule (`rollouts.baselines`),
    applied to each valid agent's last two history steps; padding agents stay at zeros."""
    rule = BASELINES.get("constant_velocity")()
    history = batch.agent_history.detach().cpu().double().numpy()  # [B, A, H, 7]
    valid = batch.history_valid.cpu().numpy() & batch.agent_valid.cpu().numpy()[..., None]
    real = batch.agent_valid.cpu().numpy()
    tracks = np.zeros((*history.shape[:3], len(StateField)))
    tracks[..., StateField.X : StateField.Y + 1] = history[..., :2]
    tracks[..., StateField.HEADING] = batch.current_state[..., 2].cpu().double().numpy()[..., None]
    tracks[..., StateField.VX : StateField.VY + 1] = history[..., 4:6]
    poses = rule.poses(tracks[real], valid[real], history.shape[2] - 1, steps)  # [N, T, 4]: x, y, z, heading
    out = np.zeros((*real.shape, steps, 4))
    last = tracks[real][:, -1, StateField.X : StateField.Y + 1]
    speed = np.linalg.norm(poses[:, :1, :2] - last[:, None], axis=-1, keepdims=True) / STEP_SECONDS
    out[real] = np.concatenate([poses[..., :2], poses[..., 3:], np.broadcast_to(speed, poses[..., :1].shape)], -1)
    return torch.as_tensor(out, dtype=batch.current_state.dtype, device=batch.current_state.device)[None]


def held_out_dataset(
    data: SampleConfig,
    labels_dir,
    *,
    split: str = "val",
    seed: int = 0,
    label_fraction: float | None = None,
    decision_first: bool | None = None,
) -> SceneDataset:
    """The windows of `split` as samples of a model trained with `data`, each with its ground-truth prompt:
    no text or history dropout. `label_fraction` (default: the training setting) is the share of the
    other labelled agents given a single-agent sentence beside an interaction prompt's agents;
    `decision_first` (default: the training setting) gives it first to the agents that decide after the current
    step (`SampleConfig.decision_first`)."""
    data = replace(data, text=True, text_dropout=0.0, history_dropout=0.0)
    if label_fraction is not None:
        data = replace(data, heuristic_label_fraction=label_fraction)
    if decision_first is not None:
        data = replace(data, decision_first=decision_first)
    return SceneDataset(labels_dir, data, split=split, seed=seed, augment=False)


def open_loop_table(
    model: LangTraj,
    data: SampleConfig,
    labels_dir,
    *,
    split: str = "val",
    num_samples: int = 6,
    steps: int = 10,
    batch_size: int = 16,
    max_windows: int | None = None,
    seed: int = 0,
    guidance_weight: float = 0.0,
    label_fraction: float | None = None,
    decision_first: bool | None = None,
) -> dict[str, float]:
    """Open-loop minADE over `num_samples` samples on held-out windows, against constant velocity.

    Every window gets its ground-truth prompt (drawn from its labels' prompt pool, no dropout), so the
    same agents are scored with and without text. Besides an interaction prompt's agents, a share
    `label_fraction` of the other labelled agents get a single-agent sentence (default: the model's
    training setting; give one value to compare models trained with different shares on the same
    agents). `prompted_text` conditions on the sentences,
    `prompted_no_text` samples with the text removed (classifier-free weight -1; with text the weight is
    `guidance_weight`, 0 = the plain conditional model). `all_*` cover every
    agent with a logged future; constant velocity is one deterministic sample.
    """
    dataset = held_out_dataset(
        data, labels_dir, split=split, seed=seed, label_fraction=label_fraction, decision_first=decision_first
    )
    count = len(dataset) if max_windows is None else min(max_windows, len(dataset))
    loader = DataLoader(Subset(dataset, list(range(count))), batch_size=batch_size, collate_fn=collate_scenes)
    sums: dict[str, list[float]] = {}

    def add(name: str, total: Tensor, n: Tensor) -> None:
        s = sums.setdefault(name, [0.0, 0.0])
        s[0] += float(total)
        s[1] += float(n)

    model = model.eval()
    has_text_branch = model.text_encoder is not None
    for index, batch in enumerate(loader):
        prompted = batch.has_text & batch.agent_valid
        cv = constant_velocity(batch, 80)
        add("cv_all", *min_ade(cv, batch))
        add("cv_prompted", *min_ade(cv, batch, prompted))
        gen = torch.Generator().manual_seed(seed + index)
        plain, _ = model.sample(batch, num_samples, steps=steps, guidance_weight=-1.0, generator=gen)
        add("model_no_text_all", *min_ade(plain, batch))
        add("model_no_text_prompted", *min_ade(plain, batch, prompted))
        if has_text_branch:
            gen.manual_seed(seed + index)
            text, _ = model.sample(batch, num_samples, steps=steps, guidance_weight=guidance_weight, generator=gen)
            add("model_text_all", *min_ade(text, batch))
            add("model_text_prompted", *min_ade(text, batch, prompted))
    out = {name: total / n for name, (total, n) in sums.items() if n}
    out["windows"] = float(count)
    out["prompted_agents"] = sums["cv_prompted"][1]
    out["scored_agents"] = sums["cv_all"][1]
    return out
