"""The open-loop experiment of docs/experiments.md: minADE over 6 samples on held-out synthesized
windows for constant velocity and each given checkpoint, with and without the ground-truth prompt.
`--text-gain` adds prompt adherence and the ceiling of the text gain (`langtraj.experiments.text_gain`).

    langtraj experiment open-loop --data LABELS_DIR --checkpoint NAME=CKPT [...] [--windows N]
        [--label-fraction 0.3] [--text-gain [--prior-samples 48]]
    langtraj experiment open-loop --config configs/experiments/open-loop.yaml   # the same as YAML

Open-loop minADE is a diagnostic: claims about realism and control come from the closed-loop tables.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import torch
from torch import Tensor
from torch.utils.data import DataLoader, Subset

from langtraj.experiments.base import EXPERIMENTS, Experiment
from langtraj.experiments.common import (
    cell,
    held_out_dataset,
    markdown_table,
    parse_named,
    require_counts,
    require_items,
)
from langtraj.experiments.text_gain import TextGainConfig, text_gain_table
from langtraj.model.checkpoint import load_model
from langtraj.model.config import SampleConfig
from langtraj.model.features import collate_scenes
from langtraj.model.langtraj import LangTraj
from langtraj.scenario.model import FUTURE_STEPS
from langtraj.sim.checkpoints import checkpoint_path
from langtraj.training.evaluation import constant_velocity, min_ade


@dataclass(frozen=True)
class NamedCheckpoint:
    """A checkpoint and its name in the tables; shorthand `NAME=PATH` (`shipped`: the packaged one)."""

    name: str
    path: Path

    @classmethod
    def parse(cls, item: str) -> NamedCheckpoint:
        name, path = parse_named(item, "--checkpoint", "NAME=PATH")
        return cls(name, Path(path))


@dataclass(frozen=True)
class OpenLoopSettings:
    """The open-loop table's settings: the labels folder whose val split is scored, the checkpoints, at most
    `windows` windows, `samples` per agent with `steps` DDIM steps and classifier-free weight `cfg`, the share of
    the other labelled agents given a single-agent sentence (`label_fraction`, the same for every checkpoint so
    that all are scored on the same agents; `decision_first`: to the agents that decide after the current step
    first), and with `text_gain` the adherence table from `prior_samples` draws without text."""

    data: Path
    checkpoints: tuple[NamedCheckpoint, ...]
    windows: int | None = None
    samples: int = 6
    steps: int = 10
    cfg: float = 0.0
    label_fraction: float = 0.3
    decision_first: bool = False
    text_gain: bool = False
    prior_samples: int = 48
    json: Path | None = None

    def __post_init__(self) -> None:
        require_items(self.checkpoints, "--checkpoint")
        require_counts(self, ("windows", "samples", "steps", "prior_samples"))


def _print_text_gain(results: dict, samples: int, prior_samples: int) -> None:
    """The adherence and ceiling table (`text_gain_table`), one row per checkpoint and agent group."""
    print(
        f"\nprompt adherence (share of samples showing the prompt's facts) and the ceiling: minADE over the "
        f"first {samples} of {prior_samples} draws without text that show them"
    )
    rows = []
    for name, r in results.items():
        g = r["text_gain"]
        for group in ("prompted", "checked"):
            if not g.get(f"{group}_agents"):
                continue
            checked = group == "checked"
            adherence = [cell(g[f"checked_adherence_{k}"]) if checked else "" for k in ("no_text", "text")]
            figures = [cell(g[f"{group}_min_ade_{k}"]) for k in ("no_text", "text", "ceiling")]
            gains = [f"{100 * g[f'{group}_{k}_gain']:.1f} %" for k in ("text", "ceiling")]
            rows.append((f"{name} ({group})", str(int(g[f"{group}_agents"])), *adherence, *figures, *gains))
    header = ("model", "agents", "adherence, no text", "adherence, text", "minADE no text", "minADE text")
    print(markdown_table((*header, "minADE ceiling", "text gain", "ceiling gain"), rows))


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
        cv = constant_velocity(batch, FUTURE_STEPS)
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


@EXPERIMENTS.register
class OpenLoopExperiment(Experiment):
    """`langtraj experiment open-loop`: minADE with and without text on held-out windows, per checkpoint (and with
    `text_gain` the adherence table)."""

    name = "open-loop"
    settings = OpenLoopSettings

    def tables(self, settings: OpenLoopSettings) -> dict[str, dict]:
        s = settings
        results = {}
        for checkpoint in s.checkpoints:
            start = time.perf_counter()
            model, data = load_model(checkpoint_path(checkpoint.path))
            shared = {"max_windows": s.windows, "label_fraction": s.label_fraction, "decision_first": s.decision_first}
            results[checkpoint.name] = open_loop_table(
                model, data, s.data, num_samples=s.samples, steps=s.steps, guidance_weight=s.cfg, **shared
            )
            if s.text_gain:
                gain_config = TextGainConfig(
                    num_samples=s.samples, prior_samples=s.prior_samples, steps=s.steps, guidance_weight=s.cfg, **shared
                )
                results[checkpoint.name]["text_gain"] = text_gain_table(model, data, s.data, gain_config, progress=True)
            results[checkpoint.name]["seconds"] = time.perf_counter() - start
        first = next(iter(results.values()))
        print(
            f"held-out windows {int(first['windows'])}, agents scored {int(first['scored_agents'])}, "
            f"prompted agents {int(first['prompted_agents'])}, minADE over {s.samples} samples (m)"
        )
        rows = [("constant velocity", cell(first["cv_all"]), cell(first["cv_prompted"]))]
        for name, r in results.items():
            rows.append((f"{name}, no text", cell(r["model_no_text_all"]), cell(r["model_no_text_prompted"])))
            if "model_text_all" in r:
                rows.append((f"{name}, ground-truth prompt", cell(r["model_text_all"]), cell(r["model_text_prompted"])))
        print(markdown_table(("model", "all agents", "prompted agents"), rows))
        if s.text_gain:
            _print_text_gain(results, s.samples, s.prior_samples)
        return results
