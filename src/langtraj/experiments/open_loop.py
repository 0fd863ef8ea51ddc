"""The open-loop experiment of docs/experiments.md: minADE over 6 samples on held-out synthesized
windows for constant velocity and each given checkpoint, with and without the ground-truth prompt.
`--text-gain` adds prompt adherence and the ceiling of the text gain (`langtraj.training.text_gain`).

    langtraj experiment open-loop --data LABELS_DIR --checkpoint NAME=CKPT [...] [--windows N]
        [--label-fraction 0.3] [--text-gain [--prior-samples 48]]
"""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from pathlib import Path

from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.model.checkpoint import load_model
from langtraj.training.evaluation import open_loop_table
from langtraj.training.text_gain import TextGainConfig, text_gain_table


def open_loop_experiment(
    labels_dir: str | Path,
    checkpoints: Sequence[str],
    *,
    windows: int | None = None,
    samples: int = 6,
    steps: int = 10,
    cfg: float = 0.0,
    label_fraction: float = 0.3,
    decision_first: bool = False,
    text_gain: bool = False,
    prior_samples: int = 48,
    json_out: str | Path | None = None,
) -> dict[str, dict]:
    """The open-loop table (and with `text_gain` the adherence table) of each checkpoint
    (`NAME=PATH`) on the held-out windows of `labels_dir`, printed as Markdown; every figure is also
    written to `json_out` when given. The same `label_fraction` and `decision_first` for every checkpoint
    score all of them on the same agents."""
    results = {}
    for item in checkpoints:
        name, sep, path = item.partition("=")
        if not sep or not path:
            raise InputError(f"expected NAME=PATH, got {item!r}", where="--checkpoint")
        start = time.perf_counter()
        model, data = load_model(path)
        results[name] = open_loop_table(
            model,
            data,
            labels_dir,
            num_samples=samples,
            steps=steps,
            max_windows=windows,
            guidance_weight=cfg,
            label_fraction=label_fraction,
            decision_first=decision_first,
        )
        if text_gain:
            gain_config = TextGainConfig(
                num_samples=samples,
                prior_samples=prior_samples,
                steps=steps,
                guidance_weight=cfg,
                max_windows=windows,
                label_fraction=label_fraction,
                decision_first=decision_first,
            )
            results[name]["text_gain"] = text_gain_table(model, data, labels_dir, gain_config, progress=True)
        results[name]["seconds"] = time.perf_counter() - start
    first = next(iter(results.values()))
    print(
        f"held-out windows {int(first['windows'])}, agents scored {int(first['scored_agents'])}, "
        f"prompted agents {int(first['prompted_agents'])}, minADE over {samples} samples (m)"
    )
    print("| model | all agents | prompted agents |\n| --- | --- | --- |")
    print(f"| constant velocity | {first['cv_all']:.3f} | {first['cv_prompted']:.3f} |")
    for name, r in results.items():
        print(f"| {name}, no text | {r['model_no_text_all']:.3f} | {r['model_no_text_prompted']:.3f} |")
        if "model_text_all" in r:
            print(f"| {name}, ground-truth prompt | {r['model_text_all']:.3f} | {r['model_text_prompted']:.3f} |")
    if text_gain:
        _print_text_gain(results, samples, prior_samples)
    if json_out:
        with atomic_path(json_out) as tmp:
            tmp.write_text(json.dumps(results, indent=2))
    return results


def _print_text_gain(results: dict, samples: int, prior_samples: int) -> None:
    """The adherence and ceiling table (`text_gain_table`), one row per checkpoint and agent group."""
    print(
        f"\nprompt adherence (share of samples showing the prompt's facts) and the ceiling: minADE over the "
        f"first {samples} of {prior_samples} draws without text that show them"
    )
    print(
        "| model | agents | adherence, no text | adherence, text | minADE no text | minADE text | "
        "minADE ceiling | text gain | ceiling gain |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |"
    )
    for name, r in results.items():
        g = r["text_gain"]
        for group in ("prompted", "checked"):
            if not g.get(f"{group}_agents"):
                continue
            adherence = (
                (f"{g['checked_adherence_no_text']:.3f}", f"{g['checked_adherence_text']:.3f}")
                if group == "checked"
                else ("", "")
            )
            print(
                f"| {name} ({group}) | {int(g[f'{group}_agents'])} | {adherence[0]} | {adherence[1]} | "
                f"{g[f'{group}_min_ade_no_text']:.3f} | {g[f'{group}_min_ade_text']:.3f} | "
                f"{g[f'{group}_min_ade_ceiling']:.3f} | {100 * g[f'{group}_text_gain']:.1f} % | "
                f"{100 * g[f'{group}_ceiling_gain']:.1f} % |"
            )
