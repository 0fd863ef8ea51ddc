"""Training samples from InterDrive windows: which sentence each agent is conditioned on, augmentation,
the dataset and batch mixing (docs/model.md, 'Training stages').

The scene features themselves (frame, agents, map, batching) belong to the model
(`langtraj.model.features`); this module adds what only training decides. Text follows the paper's
recipe (appendix, "biased sampling"): a sample carries no text at all with probability `text_dropout`,
so one network learns the conditional and the unconditional model at once (classifier-free guidance);
otherwise it carries one interaction prompt (when the window has one), every agent it mentions getting
the sentence in which it is "the target agent", and single-agent-label sentences for 30% of the other
agents that have them. `MixingSampler` upsamples interaction-labelled windows to half of every batch.
History dropout (only the current step kept) trains the model for scenes started from one observed frame.

Random choices come from a generator the caller passes: `SceneDataset` seeds one per item from
(seed, epoch, index), so a run is reproducible and workers need no shared state.
"""

from __future__ import annotations

from collections import OrderedDict
from pathlib import Path
from typing import Any

import numpy as np
from torch.utils.data import Dataset, Sampler

from langtraj.errors import InputError
from langtraj.interdrive.dataset import (
    SPLITS,
    VAL_FRACTION,
    PromptEntry,
    WindowRecord,
    in_split,
    iter_records,
    load_window,
)
from langtraj.model.config import SampleConfig
from langtraj.model.features import apply_history_dropout, map_coverage, scene_sample
from langtraj.scenario.model import Scenario
from langtraj.scenario.selection import deciders
from langtraj.training.store import FeatureStore, default_store_path, is_store, record_key

# ---------------------------------------------------------------- text


def has_interaction_prompt(record: WindowRecord | None) -> bool:
    """Whether the record's prompt pool holds an interaction prompt (one with a subtype)."""
    return record is not None and any(p.subtype is not None for p in record.prompts)


def choose_text(
    record: WindowRecord | None,
    agent_ids: np.ndarray,
    config: SampleConfig,
    rng: np.random.Generator,
    prompt: PromptEntry | None = None,
    first: frozenset[int] = frozenset(),
) -> dict[int, str]:
    """Sentences by agent slot (positions in `agent_ids`, -1 for padding; see `build_sample`). A role
    sentence names every other mentioned agent, so a prompt is used only when it `fits` the sample. Agents in
    `first` (track ids) get their single-agent sentence before any other, all of them."""
    ids = [int(i) for i in agent_ids if i >= 0]
    if prompt is not None:
        return prompt.sentences(ids)
    if record is None:
        return {}
    slots = {track: slot for slot, track in enumerate(ids)}
    text: dict[int, str] = {}
    interactions = [p for p in record.prompts if p.subtype is not None and p.fits(ids)]
    if interactions:
        chosen = interactions[int(rng.integers(len(interactions)))]
        text = chosen.sentences(ids)
    # The paper's 30 % of a scene's heuristic labels go to every sample, beside its interaction prompt.
    by_agent: dict[int, list[PromptEntry]] = {}
    for p in record.prompts:
        if p.subtype is None and p.fits(ids) and slots[p.mentions[0]] not in text:
            by_agent.setdefault(p.mentions[0], []).append(p)
    if not by_agent:
        return text
    agents = sorted(by_agent)
    count = max(1, round(config.heuristic_label_fraction * len(agents)))
    chosen = [t for t in agents if t in first]
    rest = [t for t in agents if t not in first]
    if chosen:
        chosen += rng.choice(rest, size=min(max(count - len(chosen), 0), len(rest)), replace=False).tolist()
    else:
        chosen = rng.choice(agents, size=count, replace=False).tolist()
    for track in chosen:
        options = by_agent[int(track)]
        text[slots[int(track)]] = options[int(rng.integers(len(options)))].roles[int(track)]
    return text


# ---------------------------------------------------------------- one sample


def build_sample(
    scenario: Scenario,
    record: WindowRecord | None,
    config: SampleConfig,
    rng: np.random.Generator,
    *,
    prompt: PromptEntry | None = None,
    augment: bool = True,
) -> dict[str, Any]:
    """One training sample: the window's `scene_sample` with augmentation and the agents' sentences
    (`augment_sample`). A convenience for tests and one-off use: `SceneDataset` builds samples from
    `features` instead (stored or decoded)."""
    sample = scene_sample(scenario, config)
    return augment_sample(sample, record, deciders(scenario), config, rng, prompt=prompt, augment=augment)


def augment_sample(
    sample: dict[str, Any],
    record: WindowRecord | None,
    decided: frozenset[int],
    config: SampleConfig,
    rng: np.random.Generator,
    *,
    prompt: PromptEntry | None = None,
    augment: bool = True,
) -> dict[str, Any]:
    """Augmentation and text for a `scene_sample` of a window (changed in place and returned); `decided` are
    the window's `deciders`.

    Text (only when `config.text`): with `augment`, no text at all with probability `text_dropout`.
    Otherwise `prompt`, when given, conditions every agent it mentions (and nothing else); else one
    interaction prompt of the record drawn at random (when one fits) conditions every agent it mentions,
    and single-agent-label prompts condition a random `heuristic_label_fraction` (at least one) of the
    other agents that have them, one sentence each. A prompt mentioning an agent that is not in the
    sample is never used. Without `augment` there is no dropout, but prompts are still drawn with `rng`.

    History dropout (with `augment`, probability `history_dropout`): only the current step stays valid.
    `interaction_labelled` is True when the record has an interaction prompt (or `prompt` is one).

    Draws from `rng` in a fixed order (history dropout, text dropout, prompt choice), so a seed fixes
    the sample.
    """
    drop_history = augment and rng.random() < config.history_dropout
    drop_text = augment and rng.random() < config.text_dropout
    if drop_history:
        apply_history_dropout(sample)
    if config.text and not drop_text:
        first = decided if config.decision_first else frozenset()
        for slot, sentence in choose_text(record, sample["agent_id"], config, rng, prompt, first).items():
            sample["text"][slot] = sentence
    labelled = has_interaction_prompt(record) or (prompt is not None and prompt.subtype is not None)
    sample["interaction_labelled"] = np.bool_(labelled)
    return sample


# ---------------------------------------------------------------- the dataset


class SceneDataset(Dataset):
    """Samples (`augment_sample` dicts) of the windows of an InterDrive dataset folder or a feature store,
    for a DataLoader with `collate_fn=collate_scenes`.

    `data_dir` is a labels folder (`langtraj interdrive build`) or a feature store (`langtraj features
    build`, `langtraj.training.store`; a store built from scenario files has windows without labels, for
    stage 1). With a labels folder, `store` "auto" reads the samples from the folder's store for this
    config when there is one (`default_store_path`), a path names the store to read, and None decodes every
    window; a store that lacks a window of the labels is an error (rebuild it), never a silent fallback.
    When `data_dir` is a store, `store` must stay "auto" (ValueError otherwise). With a store, a sample is
    a copy of stored arrays; without, a window is read lazily (`load_window`) and the last `cache_size`
    windows read are kept per process.

    `split` "train" / "val" keeps the windows `split_of` assigns there (`val_fraction` of the scenes,
    the same on every run and for every seed), "all" keeps every window. Scenario files are checked to
    exist up front when windows are decoded.

    Item `i` is window `i % len(self)`, built with a generator seeded from (seed, epoch, i): the same
    item is the same sample within an epoch, and `set_epoch` changes every item's augmentation (call
    it before the epoch's DataLoader iterator is made; persistent workers keep their copy). Indices past
    `len(self)` let a sampler give repeated draws of one window their own augmentation (`MixingSampler`
    does). `augment` defaults to True for "train" and False otherwise. The dataset pickles without its
    cache, for DataLoader workers.
    """

    def __init__(
        self,
        data_dir: str | Path,
        config: SampleConfig | None = None,
        *,
        split: str = "train",
        val_fraction: float = VAL_FRACTION,
        seed: int = 0,
        augment: bool | None = None,
        cache_size: int = 8,
        store: str | Path | None = "auto",
    ) -> None:
        if split not in SPLITS:
            raise ValueError(f"split must be one of {', '.join(SPLITS)}, got {split!r}")
        if not 0.0 <= val_fraction <= 1.0:
            raise ValueError(f"val_fraction must be in [0, 1], got {val_fraction}")
        self.data_dir = Path(data_dir)
        self.config = SampleConfig() if config is None else config
        self.split = split
        self.val_fraction = val_fraction
        self.seed = int(seed)
        self.augment = split == "train" if augment is None else bool(augment)
        self.cache_size = int(cache_size)
        self.epoch = 0
        self.store: FeatureStore | None = None
        rows: list[int] = []
        records: list[WindowRecord] = []
        if is_store(self.data_dir):
            if store != "auto":
                raise ValueError(f"store={store!r} given, but {self.data_dir} is itself a feature store")
            self.store = FeatureStore(self.data_dir, self.config)
            for row, entry in enumerate(self.store.rows):
                if in_split(entry.record, split, val_fraction):
                    records.append(entry.record)
                    rows.append(row)
        else:
            records = [
                rec for _, shard in iter_records(self.data_dir) for rec in shard if in_split(rec, split, val_fraction)
            ]
            self.store, rows = _store_rows(self.data_dir, self.config, records, store)
            if self.store is None:
                _check_sources(records, self.data_dir)
        self.records: tuple[WindowRecord, ...] = tuple(records)
        self._rows = np.asarray(rows, np.int64)  # each window's store row (empty without a store)
        flags = np.array([has_interaction_prompt(r) for r in records], bool)
        self._interaction = np.flatnonzero(flags)
        self._other = np.flatnonzero(~flags)
        self._cache: OrderedDict[int, Scenario] = OrderedDict()

    def __len__(self) -> int:
        return len(self.records)

    @property
    def interaction_indices(self) -> np.ndarray:
        """Windows whose prompt pool holds an interaction prompt (int64, ascending)."""
        return self._interaction.copy()

    @property
    def other_indices(self) -> np.ndarray:
        """Every other window (int64, ascending)."""
        return self._other.copy()

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def window(self, index: int) -> Scenario:
        """The scenario window of item `index` (read, or taken from the cache)."""
        pos = self._position(index)
        scene = self._cache.get(pos)
        if scene is not None:
            self._cache.move_to_end(pos)
            return scene
        record = self.records[pos]
        try:
            scene = load_window(record)
        except FileNotFoundError:
            raise InputError("scenario file not found", path=record.source) from None
        except InputError as exc:
            raise exc.located(path=record.source, where=f"window {record.scenario_id}") from None
        if self.cache_size > 0:
            self._cache[pos] = scene
            while len(self._cache) > self.cache_size:
                self._cache.popitem(last=False)
        return scene

    def _position(self, index: int) -> int:
        if not self.records:
            raise IndexError("the dataset is empty")
        index = int(index)
        if index < 0:
            if index < -len(self.records):
                raise IndexError(f"index {index} out of range")
            index += len(self.records)
        return index % len(self.records)

    def features(self, index: int) -> tuple[dict[str, Any], frozenset[int]]:
        """Item `index`'s `scene_sample` (no augmentation, no text) and its window's deciders: from the
        feature store when there is one, else from the decoded window."""
        pos = self._position(index)
        if self.store is not None:
            row = int(self._rows[pos])
            return self.store.sample(row), self.store.rows[row].deciders
        scene = self.window(pos)
        return scene_sample(scene, self.config), deciders(scene)

    def __getitem__(self, index: int) -> dict[str, Any]:
        pos = self._position(index)
        key = index if index >= 0 else pos
        rng = np.random.default_rng([self.seed, self.epoch, int(key)])
        sample, decided = self.features(pos)
        return augment_sample(sample, self.records[pos], decided, self.config, rng, augment=self.augment)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_cache"] = OrderedDict()
        return state


def _check_sources(records: list[WindowRecord], labels_dir: Path) -> None:
    """Every record's scenario file exists (checked once per file), else a one-line InputError."""
    checked: set[str] = set()
    for rec in records:
        if rec.source not in checked:
            if not Path(rec.source).is_file():
                raise InputError(
                    "scenario file not found (moved or deleted since the dataset was built?)",
                    path=rec.source,
                    where=f"labels folder {labels_dir}",
                )
            checked.add(rec.source)


def _store_rows(
    labels_dir: Path, config: SampleConfig, records: list[WindowRecord], store: str | Path | None
) -> tuple[FeatureStore | None, list[int]]:
    """The feature store to read `records` from and each record's row in it; (None, []) when there is none
    to use (`store` None, or "auto" and no store of this config). A store that lacks some record is an error."""
    if store is None:
        return None, []
    path = default_store_path(labels_dir, config) if store == "auto" else Path(store)
    if store == "auto" and not is_store(path):
        return None, []
    opened = FeatureStore(path, config)
    by_key = opened.rows_by_key()
    missing = [r for r in records if record_key(r) not in by_key]
    if missing:  # a store older than the labels: never fall back to decoding without saying so
        example = missing[0].scenario_id
        raise InputError(
            f"{len(missing)} windows of the labels are not in it (e.g. {example}); rebuild it with langtraj "
            "features build, or delete it",
            path=path,
        )
    return opened, [by_key[record_key(r)] for r in records]


class MixingSampler(Sampler[int]):
    """Indices into a `SceneDataset` where each run of `batch_size` draws holds `interaction_fraction`
    (default: the dataset config's) interaction-labelled windows, the paper's upsampling of annotated
    scenes. The count per batch is the fraction rounded with the remainder carried to the next batch,
    so the stream's share is exact; all draws come from one group when the other is empty.

    Each group is drawn without replacement, reshuffled whenever used up (interaction windows repeat
    when they are few); the order within a batch is shuffled. Epoch mode yields `num_samples` (default
    len(dataset)) indices, reshuffled by `set_epoch`; `infinite` yields forever. A draw of window `w` at
    stream position `k` (counted across epochs) is yielded as `w + len(dataset) * k`, which the dataset
    reads as window `w` with augmentation seeded by the draw, so repeats of a window differ.
    """

    def __init__(
        self,
        dataset: SceneDataset,
        batch_size: int,
        *,
        interaction_fraction: float | None = None,
        num_samples: int | None = None,
        infinite: bool = False,
        seed: int = 0,
    ) -> None:
        if batch_size < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        if len(dataset) == 0:
            raise ValueError("cannot sample from an empty dataset")
        fraction = dataset.config.interaction_fraction if interaction_fraction is None else interaction_fraction
        if not 0.0 <= fraction <= 1.0:
            raise ValueError(f"interaction_fraction must be in [0, 1], got {fraction}")
        self.size = len(dataset)
        self.interaction = np.asarray(dataset.interaction_indices, np.int64)
        self.other = np.asarray(dataset.other_indices, np.int64)
        if not len(self.interaction):
            fraction = 0.0
        elif not len(self.other):
            fraction = 1.0
        self.fraction = float(fraction)
        self.batch_size = int(batch_size)
        self.num_samples = len(dataset) if num_samples is None else int(num_samples)
        self.infinite = infinite
        self.seed = int(seed)
        self.epoch = 0

    def set_epoch(self, epoch: int) -> None:
        self.epoch = int(epoch)

    def __len__(self) -> int:
        if self.infinite:
            raise TypeError("an infinite MixingSampler has no length")
        return self.num_samples

    @staticmethod
    def window_of(index: int, size: int) -> int:
        """The window a yielded index reads, for a dataset of `size` windows."""
        return int(index) % size

    def __iter__(self):
        rng = np.random.default_rng([self.seed, self.epoch])
        pools = {True: _Cycler(self.interaction, rng), False: _Cycler(self.other, rng)}
        start = 0 if self.infinite else self.epoch * self.num_samples
        done = 0
        while self.infinite or done < self.num_samples:
            count = self.batch_size if self.infinite else min(self.batch_size, self.num_samples - done)
            wanted = round(self.fraction * (done + count)) - round(self.fraction * done)
            batch = [pools[True].next() for _ in range(wanted)] + [pools[False].next() for _ in range(count - wanted)]
            for k in rng.permutation(count).tolist():
                yield batch[k] + self.size * (start + done)
                done += 1


class _Cycler:
    """Draws from a pool without replacement, reshuffling each time it is used up."""

    def __init__(self, pool: np.ndarray, rng: np.random.Generator) -> None:
        self.pool, self.rng, self.order, self.pos = pool, rng, np.zeros(0, np.int64), 0

    def next(self) -> int:
        if self.pos >= len(self.order):
            self.order, self.pos = self.rng.permutation(self.pool), 0
        self.pos += 1
        return int(self.order[self.pos - 1])


# ---------------------------------------------------------------- map coverage


def dataset_map_coverage(dataset: SceneDataset, max_windows: int = 64) -> dict[str, float | int]:
    """The share of the agents of up to `max_windows` evenly spread windows that have a lane point of
    their sample's map within 5 m (`model.features.map_coverage`) at the current step, and at their
    logged 8-s position (agents valid there). What `langtraj train` reports before it starts."""
    count = min(len(dataset), max_windows)
    now, later, windows = [], [], np.linspace(0, len(dataset) - 1, count).round().astype(int) if count else []
    for index in windows:
        sample, _ = dataset.features(int(index))
        arrays = (sample["map_points"], sample["map_valid"], sample["map_type"])
        agents = sample["agent_valid"]
        now.append(map_coverage(arrays, sample["current_state"][:, :2], agents)[agents])
        end = sample["future_valid"][:, -1] & agents if sample["future_valid"].shape[1] else agents & False
        later.append(map_coverage(arrays, sample["future"][:, -1, :2], end)[end])
    now_all = np.concatenate(now) if now else np.zeros(0, bool)
    later_all = np.concatenate(later) if later else np.zeros(0, bool)
    return {
        "windows": int(count),
        "agents": len(now_all),
        "now": float(now_all.mean()) if len(now_all) else float("nan"),
        "at_8s": float(later_all.mean()) if len(later_all) else float("nan"),
    }
