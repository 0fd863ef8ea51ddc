"""How much the ground-truth prompt can and does change a model's samples, on held-out windows.

Two measures beside minADE (`experiments.open_loop.open_loop_table`), both from `interdrive.adherence`:

- adherence: the share of a prompted agent's samples that show its prompt's facts (label keys and
  interaction), with the prompt and without it. A model that follows its text raises it.
- the ceiling of the text gain: from `prior_samples` samples drawn without text, keep for each
  prompted agent the ones that show its prompt's facts (rejection sampling of the model's own
  prior given the labels) and take minADE over the first `num_samples` kept. That is the minADE of a
  model that follows the labels perfectly and otherwise behaves as this one; its reduction against
  the first `num_samples` draws bounds what the labels can tell this model about the logged future.
  An agent with fewer kept samples than `num_samples` is topped up with the other draws in order.

Agents whose prompt has no fact the labelers reproduce on the logged future count with their first
draws (no information) in the `prompted` figures and are left out of the `checked` ones.

See docs/model.md.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from langtraj.experiments.common import held_out_dataset
from langtraj.frames import poses_to_world
from langtraj.interdrive.adherence import AdherenceChecker, Fact, prompt_for_sentence
from langtraj.model.config import SampleConfig
from langtraj.model.features import collate_scenes
from langtraj.model.langtraj import LangTraj
from langtraj.sim.open_loop import OpenLoopSamples


@dataclass(frozen=True)
class TextGainConfig:
    """Sampling settings: `num_samples` per agent for minADE and adherence, `prior_samples` (at least
    `num_samples`) drawn without text for the ceiling, DDIM `steps`, classifier-free weight with text."""

    num_samples: int = 6
    prior_samples: int = 48
    steps: int = 10
    guidance_weight: float = 0.0
    max_windows: int | None = None
    seed: int = 0
    label_fraction: float | None = None  # share of labelled agents prompted (None: the training setting)
    decision_first: bool | None = None  # prompt the agents that decide after the current step first (None: training)

    def __post_init__(self) -> None:
        if self.num_samples < 1 or self.prior_samples < self.num_samples:
            raise ValueError("need num_samples >= 1 and prior_samples >= num_samples")


def _ade(states: np.ndarray, future: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """ADE [S, A] of scene-frame states [S, A, T, >=2] against the future [A, T, >=2] over valid steps."""
    err = np.linalg.norm(states[..., :2] - future[None, ..., :2], axis=-1)
    return (err * valid[None]).sum(-1) / np.maximum(valid.sum(-1), 1)[None]


def label_consistent_draws(follows: np.ndarray, count: int) -> np.ndarray:
    """Indices of the first `count` draws that follow the prompt (bool [K]), topped up in order with
    the others when fewer follow: the ceiling's choice for one agent."""
    kept = np.flatnonzero(follows)[:count]
    return np.concatenate([kept, np.flatnonzero(~follows)[: count - len(kept)]])


def _follow(checker: AdherenceChecker, scenario, world: np.ndarray, agents: np.ndarray, wanted) -> np.ndarray:
    """bool [S, A]: whether sample s shows the facts `wanted[a]` (all True where nothing is wanted)."""
    out = np.ones((world.shape[0], len(wanted)), bool)
    if not any(wanted):
        return out
    samples = OpenLoopSamples(agents, world, ())
    for s in range(world.shape[0]):
        found = checker.facts(samples.scenario_with(scenario, s))
        out[s] = [checker.follows(w, found) for w in wanted]
    return out


def text_gain_table(
    model: LangTraj,
    data: SampleConfig,
    labels_dir: str | Path,
    config: TextGainConfig | None = None,
    *,
    progress: bool = False,
) -> dict[str, float]:
    """Adherence with and without text, minADE with and without text, and the ceiling, over the
    prompted agents of the held-out windows (the prompts of `open_loop_table`, same seed). Labelling
    every draw dominates the time (about 5 s per window at 48 draws on one core); `progress` shows a bar."""
    config = TextGainConfig() if config is None else config
    dataset = held_out_dataset(
        data, labels_dir, seed=config.seed, label_fraction=config.label_fraction, decision_first=config.decision_first
    )
    count = len(dataset) if config.max_windows is None else min(config.max_windows, len(dataset))
    model = model.eval()
    n, k = config.num_samples, config.prior_samples
    sums: defaultdict[str, float] = defaultdict(float)
    for i in tqdm(range(count), desc="text gain", unit="win", disable=not progress):
        scenario, record, row = dataset.window(i), dataset.records[i], dataset[i]
        batch = collate_scenes([row])
        ids = batch.agent_id[0].numpy()
        future = batch.future[0].numpy()
        valid = (batch.future_valid[0] & batch.agent_valid[0][:, None]).numpy()
        slots = [a for a, sentence in enumerate(row["text"]) if sentence is not None and valid[a].any()]
        if not slots:
            continue
        generator = torch.Generator().manual_seed(config.seed + i)
        prior, _ = model.sample(batch, k, steps=config.steps, guidance_weight=-1.0, generator=generator)
        generator.manual_seed(config.seed + i)
        text, _ = model.sample(
            batch, n, steps=config.steps, guidance_weight=config.guidance_weight, generator=generator
        )
        prior, text = prior[:, 0].double().numpy(), text[:, 0].double().numpy()

        checker = AdherenceChecker.build(scenario)
        wanted: list[frozenset[Fact]] = []
        for a in slots:
            prompt = prompt_for_sentence(record, int(ids[a]), row["text"][a])
            wanted.append(frozenset() if prompt is None else checker.checkable(prompt))
        real = ids >= 0
        agents = np.array([scenario.agents.index_of(int(t)) for t in ids[real]], np.int64)
        origin = tuple(batch.origin[0].double().tolist())
        follow_prior = _follow(checker, scenario, poses_to_world(prior[:, real], origin), agents, wanted)
        follow_text = _follow(checker, scenario, poses_to_world(text[:, real], origin), agents, wanted)

        ade_prior = _ade(prior[:, slots], future[slots], valid[slots])
        ade_text = _ade(text[:, slots], future[slots], valid[slots])
        for j, want in enumerate(wanted):
            chosen = label_consistent_draws(follow_prior[:, j], n)
            base, best, cond = ade_prior[:n, j].min(), ade_prior[chosen, j].min(), ade_text[:, j].min()
            groups = ("prompted", "checked") if want else ("prompted",)
            for group in groups:
                sums[f"{group}_agents"] += 1
                sums[f"{group}_min_ade_no_text"] += base
                sums[f"{group}_min_ade_text"] += cond
                sums[f"{group}_min_ade_ceiling"] += best
            if want:
                sums["checked_adherence_no_text"] += follow_prior[:n, j].mean()
                sums["checked_adherence_text"] += follow_text[:, j].mean()
                sums["checked_prior_adherence"] += follow_prior[:, j].mean()
                sums["checked_full_ceiling"] += float(follow_prior[:, j].sum() >= n)
    out: dict[str, float] = {"windows": float(count)}
    for group in ("prompted", "checked"):
        agents = sums.get(f"{group}_agents", 0.0)
        out[f"{group}_agents"] = agents
        for name, total in sums.items():
            if name.startswith(group + "_") and name != f"{group}_agents" and agents:
                out[name] = total / agents
    for group in ("prompted", "checked"):
        if out.get(f"{group}_min_ade_no_text"):
            out[f"{group}_ceiling_gain"] = 1.0 - out[f"{group}_min_ade_ceiling"] / out[f"{group}_min_ade_no_text"]
            out[f"{group}_text_gain"] = 1.0 - out[f"{group}_min_ade_text"] / out[f"{group}_min_ade_no_text"]
    return out
