"""Open-loop measures used in validation and experiments: minADE over samples, constant velocity."""

from __future__ import annotations

import torch
from torch import Tensor

from langtraj.model.batch import SceneBatch


def ade_per_sample(states: Tensor, batch: SceneBatch) -> tuple[Tensor, Tensor]:
    """ADE [S, B, A] of sampled states [S, B, A, T, >=2] against the logged future, over valid steps,
    and which agents have any valid future step (bool [B, A])."""
    valid = batch.future_valid & batch.agent_valid[..., None]
    count = valid.sum(-1)
    err = torch.linalg.norm(states[..., :2] - batch.future[None, ..., :2], dim=-1)
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
    """States [1, B, A, T, 4] keeping each agent's current speed and heading (scene frame)."""
    x, y, heading, speed = batch.current_state.unbind(-1)
    t = torch.arange(1, steps + 1, device=x.device, dtype=x.dtype) * 0.1
    px = x[..., None] + speed[..., None] * torch.cos(heading)[..., None] * t
    py = y[..., None] + speed[..., None] * torch.sin(heading)[..., None] * t
    return torch.stack([px, py, heading[..., None].expand_as(px), speed[..., None].expand_as(px)], -1)[None]


def held_out_dataset(module, labels_dir, *, split: str = "val", seed: int = 0, label_fraction: float | None = None):
    """The windows of `split` as the module's samples with every window's ground-truth prompt: no text
    or history dropout. `label_fraction` (default: the module's training setting) is the share of the
    other labelled agents given a single-agent sentence beside an interaction prompt's agents."""
    from dataclasses import replace

    from langtraj.training.data import SceneDataset

    data = replace(module.train_config.data, text=True, text_dropout=0.0, history_dropout=0.0)
    if label_fraction is not None:
        data = replace(data, heuristic_label_fraction=label_fraction)
    return SceneDataset(labels_dir, data, split=split, seed=seed, augment=False)


def open_loop_table(
    module,
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
) -> dict[str, float]:
    """Open-loop minADE over `num_samples` samples on held-out windows, against constant velocity.

    Every window gets its ground-truth prompt (drawn from its labels' prompt pool, no dropout), so the
    same agents are scored with and without text. Besides an interaction prompt's agents, a share
    `label_fraction` of the other labelled agents get a single-agent sentence (default: the module's
    training setting; give one value to compare models trained with different shares on the same
    agents). `prompted_text` conditions on the sentences,
    `prompted_no_text` samples with the text removed (classifier-free weight -1; with text the weight is
    `guidance_weight`, 0 = the plain conditional model). `all_*` cover every
    agent with a logged future; constant velocity is one deterministic sample.
    """
    from torch.utils.data import DataLoader, Subset

    from langtraj.training.data import collate_scenes

    dataset = held_out_dataset(module, labels_dir, split=split, seed=seed, label_fraction=label_fraction)
    count = len(dataset) if max_windows is None else min(max_windows, len(dataset))
    loader = DataLoader(Subset(dataset, list(range(count))), batch_size=batch_size, collate_fn=collate_scenes)
    sums: dict[str, list[float]] = {}

    def add(name: str, total: Tensor, n: Tensor) -> None:
        s = sums.setdefault(name, [0.0, 0.0])
        s[0] += float(total)
        s[1] += float(n)

    model = module.model.eval()
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
