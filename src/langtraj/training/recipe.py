"""The training recipe: one command from SUMO synthesis to the shipped checkpoint (docs/model.md,
'The recipe').

A recipe (`configs/recipes/*.yaml`) names the corpus to synthesize, the label build, and the training
stages in order (stage 1, stage 2, distillation to K = 5, closed-loop training), each a `configs/`
preset. Every stage starts from the previous stage's last checkpoint, resumes from its own when it was
cut off, and is skipped when done (its run folder holds `DONE.json`, written last, with its time); so
rerunning the command after a kill continues where it stopped. The time of each stage is printed and
kept in `RUN/recipe.json`.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from langtraj.errors import InputError
from langtraj.fileio import atomic_path
from langtraj.settings import dataclass_kwargs, require
from langtraj.training.config import load_config, read_yaml


@dataclass(frozen=True)
class CorpusStep:
    """`langtraj synth` settings of the recipe's corpus."""

    kinds: str = "all"
    windows: int = 3000
    seed: int = 11

    def __post_init__(self) -> None:
        require(self.windows >= 1, "corpus.windows", f"must be >= 1, got {self.windows}")


@dataclass(frozen=True)
class TrainStep:
    """One training stage: its name (its run folder) and its preset, relative to the recipe file."""

    name: str
    config: str

    def __post_init__(self) -> None:
        require(bool(self.name) and "/" not in self.name, "stages.name", f"bad stage name {self.name!r}")


@dataclass(frozen=True)
class Recipe:
    """A whole training chain; `folder` is where the recipe file lies (stage presets are relative to it)."""

    name: str
    corpus: CorpusStep = field(default_factory=CorpusStep)
    label_seed: int = 0
    stages: tuple[TrainStep, ...] = ()
    ship: str | None = None  # the stage whose last checkpoint is the recipe's output (None: the last stage)
    folder: Path = Path(".")

    def __post_init__(self) -> None:
        require(bool(self.stages), "stages", "a recipe needs at least one training stage")
        names = [s.name for s in self.stages]
        require(len(set(names)) == len(names), "stages", f"stage names repeat: {names}")
        require(self.ship is None or self.ship in names, "ship", f"{self.ship!r} is not a stage: {names}")

    @property
    def shipped_stage(self) -> str:
        """The stage whose last checkpoint the recipe hands out."""
        return self.ship or self.stages[-1].name


def load_recipe(path: str | Path) -> Recipe:
    """The recipe at `path`, or a one-line InputError naming the file and field."""
    path = Path(path)
    data = read_yaml(path)
    try:
        data = dataclass_kwargs(Recipe, data, str(path))
        corpus = CorpusStep(**dataclass_kwargs(CorpusStep, data.pop("corpus", {}), "corpus"))
        raw = data.pop("stages", [])
        if not isinstance(raw, list):
            raise InputError("expected a list of {name, config}", where="stages")
        stages = tuple(TrainStep(**dataclass_kwargs(TrainStep, s, "stages")) for s in raw)
        recipe = Recipe(corpus=corpus, stages=stages, folder=path.resolve().parent, **data)
        for stage in recipe.stages:
            load_config(recipe.folder / stage.config)  # every preset checked before anything runs
        return recipe
    except TypeError as exc:
        raise InputError(str(exc), path=path) from None
    except InputError as exc:
        raise exc.located(path=path) from None


def _done(folder: Path) -> dict[str, Any] | None:
    marker = folder / "DONE.json"
    return json.loads(marker.read_text()) if marker.is_file() else None


def _finish(folder: Path, record: dict[str, Any]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    with atomic_path(folder / "DONE.json") as tmp:
        tmp.write_text(json.dumps(record, indent=2))


def run_recipe(
    recipe: Recipe,
    out: str | Path,
    *,
    workers: int = 2,
    max_steps: int | None = None,
    say: Callable[[str], None] = print,
) -> Path:
    """Run (or resume) `recipe` into `out`: `corpus/`, `labels/`, one folder per stage. Returns the final
    checkpoint of the stage it ships (`Recipe.shipped_stage`). `max_steps` caps every stage (smoke runs)."""
    from langtraj.interdrive.dataset import BuildConfig, build_dataset
    from langtraj.scenario.io import expand_scenario_paths
    from langtraj.synth.factory import FactoryConfig, run_factory
    from langtraj.synth.network import parse_kinds
    from langtraj.training.run import train

    out = Path(out)
    times: dict[str, float] = {}

    def step(name: str, folder: Path, work: Callable[[], dict[str, Any]]) -> dict[str, Any]:
        done = _done(folder)
        if done is not None:
            say(f"{name}: done before ({done['seconds']:.0f} s), skipped")
            times[name] = done["seconds"]
            return done
        begin = time.perf_counter()
        record = work()
        record["seconds"] = time.perf_counter() - begin
        _finish(folder, record)
        times[name] = record["seconds"]
        say(f"{name}: {record['seconds'] / 60:.1f} min")
        return record

    corpus, labels = out / "corpus", out / "labels"
    c = recipe.corpus
    step(
        "corpus",
        corpus,
        lambda: {
            "windows": run_factory(
                FactoryConfig(kinds=parse_kinds(c.kinds), windows=c.windows, seed=c.seed, out=corpus, workers=workers)
            )["windows"]
        },
    )
    step(
        "labels",
        labels,
        lambda: {
            "windows": build_dataset(
                expand_scenario_paths([corpus / "shards"]), labels, BuildConfig(seed=recipe.label_seed), workers
            )["windows"]
        },
    )
    previous: Path | None = None
    for stage in recipe.stages:
        folder = out / stage.name
        config = load_config(recipe.folder / stage.config)
        if previous is not None:
            config = replace(config, init_from=str(previous))
        step(
            stage.name,
            folder,
            lambda config=config, folder=folder, preset=stage.config: {
                "checkpoint": str(train(config, labels, folder, resume="auto", max_steps=max_steps, progress=False)),
                "config": asdict(config) | {"preset": preset},
            },
        )
        previous = folder / "checkpoints" / "last.ckpt"
    shipped = out / recipe.shipped_stage / "checkpoints" / "last.ckpt"
    with atomic_path(out / "recipe.json") as tmp:
        tmp.write_text(json.dumps({"recipe": recipe.name, "seconds": times, "shipped": str(shipped)}, indent=2))
    say("recipe " + recipe.name + ": " + ", ".join(f"{k} {v / 60:.1f} min" for k, v in times.items()))
    say(f"shipped checkpoint ({recipe.shipped_stage}): {shipped}")
    return shipped
