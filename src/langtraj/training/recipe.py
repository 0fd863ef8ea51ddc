"""The training recipe: one command from SUMO synthesis to the shipped checkpoint (docs/model.md,
'The recipe').

A recipe (`configs/recipes/*.yaml`) names the corpus to synthesize, how much of it to label, and the
training stages in order (stage 1, stage 2, distillation to K = 5, closed-loop training), each a
`configs/` preset reading either every corpus window without labels (`data: corpus`, stage 1) or the
labelled windows (`data: labels`). Each stage's samples are computed once into a feature store
(`langtraj.training.store`) before it trains. Every stage starts from the previous stage's last
checkpoint, resumes from its own when it was cut off, and is skipped when done (its run folder holds
`DONE.json`, written last, with its time); so rerunning the command after a kill continues where it
stopped. The time of each step is printed and kept in `RUN/recipe.json`.
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
from langtraj.settings import dataclass_kwargs, read_yaml, require
from langtraj.training.config import load_config


@dataclass(frozen=True)
class CorpusStep:
    """`langtraj synth` settings of the recipe's corpus."""

    kinds: str = "all"
    windows: int = 3000
    seed: int = 11

    def __post_init__(self) -> None:
        require(self.windows >= 1, "corpus.windows", f"must be >= 1, got {self.windows}")


@dataclass(frozen=True)
class LabelStep:
    """How much of the corpus is labelled for the stages that read labels: whole shards, taken in turn from
    each kind, until `windows` windows are covered (None: every shard)."""

    windows: int | None = None

    def __post_init__(self) -> None:
        require(self.windows is None or self.windows >= 1, "labels.windows", f"must be >= 1, got {self.windows}")


DATA_SOURCES = ("labels", "corpus")


@dataclass(frozen=True)
class TrainStep:
    """One training stage: its name (its run folder), its preset (relative to the recipe file), and what it
    reads: "labels" (the labelled windows) or "corpus" (every corpus window, no labels: stage 1)."""

    name: str
    config: str
    data: str = "labels"

    def __post_init__(self) -> None:
        require(bool(self.name) and "/" not in self.name, "stages.name", f"bad stage name {self.name!r}")
        require(self.data in DATA_SOURCES, "stages.data", f"must be one of {DATA_SOURCES}, got {self.data!r}")


@dataclass(frozen=True)
class Recipe:
    """A whole training chain; `folder` is where the recipe file lies (stage presets are relative to it)."""

    name: str
    corpus: CorpusStep = field(default_factory=CorpusStep)
    labels: LabelStep = field(default_factory=LabelStep)
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
        labels = LabelStep(**dataclass_kwargs(LabelStep, data.pop("labels", {}), "labels"))
        raw = data.pop("stages", [])
        if not isinstance(raw, list):
            raise InputError("expected a list of {name, config}", where="stages")
        stages = tuple(TrainStep(**dataclass_kwargs(TrainStep, s, "stages")) for s in raw)
        recipe = Recipe(corpus=corpus, labels=labels, stages=stages, folder=path.resolve().parent, **data)
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


def corpus_shards(corpus: Path, windows: int | None = None) -> list[Path]:
    """The corpus's shards as its manifest lists them (not whatever else lies in its folder): every one with
    windows when `windows` is None, else whole shards taken in turn from each kind (manifest order within a
    kind) until `windows` windows are covered, so every kind is in the subset (the labelled one). Files in
    manifest order."""
    from langtraj.synth.factory import read_factory_manifest

    shards = [s for s in read_factory_manifest(corpus)["shards"] if s["windows"]]
    if windows is None:
        return [corpus / s["file"] for s in shards]
    by_kind: dict[str, list[dict[str, Any]]] = {}
    for shard in shards:
        by_kind.setdefault(shard["kind"], []).append(shard)
    chosen, covered = [], 0
    for turn in range(max((len(v) for v in by_kind.values()), default=0)):
        for kind_shards in by_kind.values():
            if covered < windows and turn < len(kind_shards):
                chosen.append(kind_shards[turn]["file"])
                covered += kind_shards[turn]["windows"]
    keep = set(chosen)
    return [corpus / s["file"] for s in shards if s["file"] in keep]


def run_recipe(
    recipe: Recipe,
    out: str | Path,
    *,
    workers: int = 2,
    max_steps: int | None = None,
    say: Callable[[str], None] = print,
) -> Path:
    """Run (or resume) `recipe` into `out`: `corpus/`, `labels/`, `features/` (stage-1 stores of the corpus),
    one folder per stage. Returns the final checkpoint of the stage it ships (`Recipe.shipped_stage`).
    `max_steps` caps every stage (smoke runs)."""
    from langtraj.interdrive.dataset import BuildConfig, build_dataset
    from langtraj.synth.factory import FactoryConfig, run_factory
    from langtraj.synth.network import parse_kinds
    from langtraj.training.run import train
    from langtraj.training.store import (
        build_store,
        default_store_path,
        is_store,
        labelled_jobs,
        scenario_jobs,
        store_digest,
    )

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

    def stored(name: str, path: Path, jobs: Callable[[], list]) -> Path:
        """The feature store at `path`, built (or its build resumed) first when it is not finished."""
        if not is_store(path):
            begin = time.perf_counter()
            build_store(jobs(), path, workers=workers, say=say)
            times[name] = time.perf_counter() - begin
            say(f"{name}: {times[name] / 60:.1f} min")
        return path

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
    if any(s.data == "labels" for s in recipe.stages):
        step(
            "labels",
            labels,
            lambda: {
                "windows": build_dataset(
                    corpus_shards(corpus, recipe.labels.windows), labels, BuildConfig(seed=recipe.label_seed), workers
                )["windows"]
            },
        )
    previous: Path | None = None
    for stage in recipe.stages:
        folder = out / stage.name
        config = load_config(recipe.folder / stage.config)
        if previous is not None:
            config = replace(config, init_from=str(previous))
        data = labels
        if _done(folder) is None:
            if stage.data == "corpus":
                data = stored(
                    f"features {stage.name}",
                    out / "features" / f"corpus-{store_digest(config.data)}",
                    lambda config=config: scenario_jobs(corpus_shards(corpus), config.data),
                )
            else:
                stored(
                    f"features {stage.name}",
                    default_store_path(labels, config.data),
                    lambda config=config: labelled_jobs(labels, config.data),
                )
        step(
            stage.name,
            folder,
            lambda config=config, folder=folder, preset=stage.config, data=data: {
                "checkpoint": str(train(config, data, folder, resume="auto", max_steps=max_steps, progress=False)),
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
