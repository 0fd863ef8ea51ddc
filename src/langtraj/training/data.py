"""From InterDrive windows to `SceneBatch`es: scene-frame samples, text selection, and batch mixing.

One training sample is one window (a scene) in its own frame: the focal agent (the SDC, else the most
important agent) at the origin heading along +x, so every scene looks alike to the network. A sample
holds the `max_agents` most important agents valid at the current step (`prioritized_agents`), their
history and future, the nearby map as fixed-size polylines, and per agent the sentence it is
conditioned on, or None.

Text follows the paper's recipe (appendix, "biased sampling"): a sample carries no text at all with
probability `text_dropout`, so one network learns the conditional and the unconditional model at once
(classifier-free guidance); otherwise it carries one interaction prompt (when the window has one),
every agent it mentions getting the sentence in which it is "the target agent", and single-agent-label
sentences for 30% of the other agents that have them. `MixingSampler` upsamples
interaction-labelled windows to half of every batch. History dropout (only the current step kept)
trains the model for scenes started from one observed frame.

Random choices come from a generator the caller passes: `SceneDataset` seeds one per item from
(seed, epoch, index), so a run is reproducible and workers need no shared state.
"""

from __future__ import annotations

import hashlib
import math
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.utils.data import Dataset, Sampler

from langtraj.angles import wrap_angle
from langtraj.errors import InputError
from langtraj.frames import points_to_frame
from langtraj.interdrive.dataset import PromptEntry, WindowRecord, iter_records, load_window
from langtraj.model.batch import AGENT_HISTORY_FEATURES, SceneBatch
from langtraj.scenario.model import STEP_SECONDS, RoadMap, Scenario
from langtraj.scenario.selection import prioritized_agents
from langtraj.scenario.types import MapFeatureType, StateField

MAP_TYPES = frozenset(
    {t for t in MapFeatureType if t.is_lane or t.is_road_line or t.is_road_edge}
    | {MapFeatureType.CROSSWALK, MapFeatureType.SPEED_BUMP, MapFeatureType.STOP_SIGN}
)
"""Map feature types a sample encodes (driveways are left out)."""

MAP_POINT_SPACING = 2.0
"""Largest gap (m) between consecutive resampled map points: a piece spans at most (P - 1) * 2 m."""

MOVING_SPEED = 0.5
"""Speed (m/s) from positions above which a near-zero reported velocity counts as missing."""

_STILL_SPEED = 0.05  # reported speeds below this (m/s) may be a source's placeholder for "unknown"


@dataclass(frozen=True)
class SampleConfig:
    """What a sample holds and how it is augmented.

    Sizes: `max_agents` agents, `max_polylines` map polylines of `points_per_polyline` points within
    `map_radius` m of the origin, `history_steps` steps ending at the current one, `future_steps` after it.
    `text` False is stage 1 (no text at all). The fractions are probabilities per sample (dropouts), a
    share of a scene's labelled agents (`heuristic_label_fraction`) and a share of each batch
    (`interaction_fraction`, used by `MixingSampler`).
    """

    max_agents: int = 32
    max_polylines: int = 96
    points_per_polyline: int = 20
    history_steps: int = 11
    future_steps: int = 80
    map_radius: float = 80.0
    text: bool = True
    text_dropout: float = 0.5
    history_dropout: float = 0.5
    heuristic_label_fraction: float = 0.3
    interaction_fraction: float = 0.5

    def __post_init__(self) -> None:
        for name in ("max_agents", "max_polylines", "history_steps"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.points_per_polyline < 2:
            raise ValueError(f"points_per_polyline must be >= 2, got {self.points_per_polyline}")
        if self.future_steps < 0 or self.map_radius <= 0:
            raise ValueError("future_steps must be >= 0 and map_radius > 0")
        for name in ("text_dropout", "history_dropout", "heuristic_label_fraction", "interaction_fraction"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")


# ---------------------------------------------------------------- the scene frame


def scene_frame(scenario: Scenario) -> tuple[float, float, float]:
    """World (x, y, heading) of the scene frame: the SDC at the current step when it is valid there,
    else the first of `prioritized_agents`; (0, 0, 0) when no agent is valid at the current step."""
    t = scenario.current_index
    agents = scenario.agents
    focal = scenario.sdc_index
    if focal < 0 or not agents.valid[focal, t]:
        order = prioritized_agents(scenario, 1)
        if not len(order):
            return 0.0, 0.0, 0.0
        focal = int(order[0])
    state = agents.states[focal, t]
    return float(state[StateField.X]), float(state[StateField.Y]), float(wrap_angle(state[StateField.HEADING]))


def _rotate(vec: np.ndarray, heading: float) -> np.ndarray:
    """World vectors [..., 2] (velocities) in a frame rotated by `heading`."""
    c, s = math.cos(heading), math.sin(heading)
    vec = np.asarray(vec, np.float64)
    return np.stack([c * vec[..., 0] + s * vec[..., 1], -s * vec[..., 0] + c * vec[..., 1]], axis=-1)


def _velocities(states: np.ndarray, valid: np.ndarray, timestamps: np.ndarray) -> np.ndarray:
    """World velocities [A, T, 2], with missing ones estimated from positions.

    A reported velocity counts as missing when it is not finite, or when it is (near) zero while the
    backward difference of positions says the agent moves faster than `MOVING_SPEED` (some sources
    write zeros for "unknown"). Missing velocities become that backward difference (previous step to
    this one; never a later step, so nothing leaks from the future) where both steps are valid, else 0.
    """
    vel = states[..., StateField.VX : StateField.VY + 1].astype(np.float64)
    xy = states[..., StateField.X : StateField.Y + 1].astype(np.float64)
    dt = np.diff(np.asarray(timestamps, np.float64))
    dt = np.where(dt > 0, dt, STEP_SECONDS)
    diff = np.zeros_like(vel)
    diff[:, 1:] = (xy[:, 1:] - xy[:, :-1]) / dt[None, :, None]
    have_diff = np.zeros(valid.shape, bool)
    have_diff[:, 1:] = valid[:, 1:] & valid[:, :-1]
    finite = np.isfinite(vel).all(axis=-1)
    speed = np.linalg.norm(np.where(finite[..., None], vel, 0.0), axis=-1)
    moving = have_diff & (np.linalg.norm(diff, axis=-1) > MOVING_SPEED)
    missing = ~finite | ((speed < _STILL_SPEED) & moving)
    fill = np.where(have_diff[..., None], diff, 0.0)
    return np.where(missing[..., None], fill, vel)


def _steps(start: int, count: int, num_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """`count` step indices from `start` clipped into the scene, and which of them are inside it."""
    steps = np.arange(start, start + count)
    inside = (steps >= 0) & (steps < num_steps)
    return np.clip(steps, 0, max(num_steps - 1, 0)), inside


# ---------------------------------------------------------------- the map


def _bbox_distance(xy: np.ndarray) -> float:
    """Distance from the origin to the bounding box of points [N, 2] (a lower bound on the nearest one)."""
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    gap = np.maximum(np.maximum(lo, -hi), 0.0)
    return float(np.hypot(gap[0], gap[1]))


def _pieces(xy: np.ndarray, points: int) -> np.ndarray:
    """A polyline [N, 2] cut into equal pieces of at most (points - 1) * MAP_POINT_SPACING m, each
    resampled uniformly by arc length to `points` points: [K, points, 2]. A polyline of no length gives
    one piece holding only its first point (then padded, see `map_polylines`)."""
    seg = np.linalg.norm(np.diff(xy, axis=0), axis=-1)
    keep = np.concatenate([[True], seg > 1e-9])
    xy, seg = xy[keep], seg[seg > 1e-9]
    total = float(seg.sum())
    if len(xy) < 2 or total <= 1e-9:
        return xy[None, :1]
    count = math.ceil(total / ((points - 1) * MAP_POINT_SPACING) - 1e-9)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = (np.arange(count)[:, None] + np.linspace(0.0, 1.0, points)[None]) * (total / count)
    return np.stack([np.interp(s, cum, xy[:, 0]), np.interp(s, cum, xy[:, 1])], axis=-1)


def map_polylines(
    road_map: RoadMap, origin: tuple[float, float, float], config: SampleConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Map points [M, P, 2] (scene frame), validity [M, P] and types [M] of the polylines nearest the
    origin. Features of `MAP_TYPES` are cut and resampled (`_pieces`; area polygons closed first); a
    piece is kept when its nearest point is within `map_radius`, nearest first. A single-point feature
    (a stop sign) is a polyline with only its first point valid."""
    m, p = config.max_polylines, config.points_per_polyline
    ox, oy, _ = origin
    found: list[tuple[float, int, int, np.ndarray]] = []  # (distance, order, type, points [P|1, 2] centred)
    for feature in road_map.features:
        if feature.type not in MAP_TYPES or not len(feature.points):
            continue
        xy = feature.points[:, :2] - (ox, oy)
        if _bbox_distance(xy) > config.map_radius:
            continue
        if feature.type.is_area and len(xy) > 2:
            xy = np.concatenate([xy, xy[:1]])
        pieces = _pieces(xy, p)
        dist = np.linalg.norm(pieces, axis=-1).min(axis=-1)
        for k in np.flatnonzero(dist <= config.map_radius):
            found.append((float(dist[k]), len(found), int(feature.type), pieces[k]))
    found.sort(key=lambda item: item[:2])
    points = np.zeros((m, p, 2), np.float32)
    valid = np.zeros((m, p), bool)
    types = np.zeros(m, np.int64)
    for row, (_, _, kind, piece) in enumerate(found[:m]):
        local = points_to_frame(piece + (ox, oy), origin)
        points[row, : len(local)] = local
        valid[row, : len(local)] = True
        types[row] = kind
    return points, valid, types


# ---------------------------------------------------------------- text


def has_interaction_prompt(record: WindowRecord | None) -> bool:
    """Whether the record's prompt pool holds an interaction prompt (one with a subtype)."""
    return record is not None and any(p.subtype is not None for p in record.prompts)


def _prompt_fits(prompt: PromptEntry, slots: dict[int, int]) -> bool:
    return bool(prompt.mentions) and all(m in slots and m in prompt.roles for m in prompt.mentions)


def _choose_text(
    record: WindowRecord | None,
    slots: dict[int, int],
    config: SampleConfig,
    rng: np.random.Generator,
    prompt: PromptEntry | None,
) -> dict[int, str]:
    """Sentences by agent slot (see `build_sample`). A role sentence names every other mentioned agent
    ("other agent1", ...), so a prompt is used only when all its mentioned agents are in the sample."""
    if prompt is not None:
        return {slots[m]: prompt.roles[m] for m in prompt.mentions} if _prompt_fits(prompt, slots) else {}
    if record is None:
        return {}
    text: dict[int, str] = {}
    interactions = [p for p in record.prompts if p.subtype is not None and _prompt_fits(p, slots)]
    if interactions:
        chosen = interactions[int(rng.integers(len(interactions)))]
        text = {slots[m]: chosen.roles[m] for m in chosen.mentions}
    # The paper's 30 % of a scene's heuristic labels go to every sample, beside its interaction prompt.
    by_agent: dict[int, list[PromptEntry]] = {}
    for p in record.prompts:
        if p.subtype is None and _prompt_fits(p, slots) and slots[p.mentions[0]] not in text:
            by_agent.setdefault(p.mentions[0], []).append(p)
    if not by_agent:
        return text
    agents = sorted(by_agent)
    count = max(1, round(config.heuristic_label_fraction * len(agents)))
    for track in rng.choice(agents, size=count, replace=False).tolist():
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
    agents: np.ndarray | None = None,
    origin: tuple[float, float, float] | None = None,
    map_arrays: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> dict[str, Any]:
    """One scene row of a `SceneBatch` as numpy arrays (no batch axis), keyed by `SceneBatch` field names.

    `agents` (scenario rows, at most `max_agents`), `origin` and `map_arrays` (from `map_polylines` for
    that origin) override the choices below: closed-loop simulation keeps them fixed across replans.

    Agents: `prioritized_agents(scenario, max_agents)` (all valid at the current step), padded to
    `max_agents` (padding: invalid, type 0, id -1, zeros). History is the `history_steps` steps ending
    at the current one; future the `future_steps` after it; steps outside the scene are invalid. Values
    are in the scene frame (`scene_frame`); headings are wrapped to (-pi, pi]; invalid steps are zeros.
    `current_state` speed is |v| of the reported velocity, or of the backward position difference where
    the velocity is missing (`_velocities`); history vx, vy use the same velocities.

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
    a_max, h, f = config.max_agents, config.history_steps, config.future_steps
    t0 = scenario.current_index
    origin = scene_frame(scenario) if origin is None else origin
    heading0 = origin[2]
    chosen = prioritized_agents(scenario, a_max) if agents is None else np.asarray(agents, np.int64)
    if len(chosen) > a_max:
        raise ValueError(f"{len(chosen)} agents given, the sample holds at most {a_max}")
    n = len(chosen)
    agents = scenario.agents
    states = agents.states[chosen]
    valid = agents.valid[chosen]
    vel = _velocities(states, valid, scenario.timestamps)
    xy = points_to_frame(states[..., StateField.X : StateField.Y + 1], origin)
    heading = wrap_angle(states[..., StateField.HEADING].astype(np.float64) - heading0)
    vel_local = _rotate(vel, heading0)

    drop_history = augment and rng.random() < config.history_dropout
    drop_text = augment and rng.random() < config.text_dropout

    hist_steps, hist_inside = _steps(t0 - h + 1, h, scenario.num_steps)
    hist_valid = np.zeros((a_max, h), bool)
    hist_valid[:n] = valid[:, hist_steps] & hist_inside[None]
    if drop_history:
        hist_valid[:, :-1] = False
    history = np.zeros((a_max, h, AGENT_HISTORY_FEATURES), np.float32)
    hh = heading[:, hist_steps]
    history[:n] = np.concatenate(
        [xy[:, hist_steps], np.cos(hh)[..., None], np.sin(hh)[..., None], vel_local[:, hist_steps], np.ones((n, h, 1))],
        axis=-1,
    )
    history[~hist_valid] = 0.0

    fut_steps, fut_inside = _steps(t0 + 1, f, scenario.num_steps)
    fut_valid = np.zeros((a_max, f), bool)
    fut_valid[:n] = valid[:, fut_steps] & fut_inside[None]
    future = np.zeros((a_max, f, 3), np.float32)
    future[:n] = np.concatenate([xy[:, fut_steps], heading[:, fut_steps, None]], axis=-1)
    future[~fut_valid] = 0.0

    current = np.zeros((a_max, 4), np.float32)
    current[:n, :2] = xy[:, t0]
    current[:n, 2] = heading[:, t0]
    current[:n, 3] = np.linalg.norm(vel[:, t0], axis=-1)
    size = np.zeros((a_max, 2), np.float32)
    size[:n] = states[:, t0, StateField.LENGTH : StateField.WIDTH + 1]
    agent_type = np.zeros(a_max, np.int64)
    agent_type[:n] = agents.types[chosen]
    agent_id = np.full(a_max, -1, np.int64)
    agent_id[:n] = agents.ids[chosen]
    agent_valid = np.zeros(a_max, bool)
    agent_valid[:n] = True

    text: list[str | None] = [None] * a_max
    if config.text and not drop_text:
        slots = {int(track): slot for slot, track in enumerate(agent_id[:n])}
        for slot, sentence in _choose_text(record, slots, config, rng, prompt).items():
            text[slot] = sentence

    map_points, map_valid, map_type = map_arrays or map_polylines(scenario.road_map, origin, config)
    labelled = has_interaction_prompt(record) or (prompt is not None and prompt.subtype is not None)
    return {
        "agent_history": history,
        "history_valid": hist_valid,
        "agent_type": agent_type,
        "agent_size": size,
        "agent_valid": agent_valid,
        "current_state": current,
        "future": future,
        "future_valid": fut_valid,
        "map_points": map_points,
        "map_valid": map_valid,
        "map_type": map_type,
        "text": text,
        "interaction_labelled": np.bool_(labelled),
        "origin": np.asarray(origin, np.float32),
        "agent_id": agent_id,
        "scenario_id": scenario.scenario_id,
    }


_FLOAT = ("agent_history", "agent_size", "current_state", "future", "map_points", "origin")
_BOOL = ("history_valid", "agent_valid", "future_valid", "map_valid", "interaction_labelled")
_LONG = ("agent_type", "map_type", "agent_id")


def collate_scenes(samples: Sequence[dict[str, Any]]) -> SceneBatch:
    """Stack samples of one `SampleConfig` (equal sizes) into a `SceneBatch`; usable as a DataLoader
    `collate_fn`."""
    if not samples:
        raise ValueError("cannot collate an empty list of samples")
    tensors: dict[str, Any] = {}
    for names, dtype in ((_FLOAT, torch.float32), (_BOOL, torch.bool), (_LONG, torch.long)):
        for name in names:
            tensors[name] = torch.as_tensor(np.stack([s[name] for s in samples]), dtype=dtype)
    return SceneBatch(
        **tensors,
        text=[list(s["text"]) for s in samples],
        scenario_id=[str(s["scenario_id"]) for s in samples],
    )


# ---------------------------------------------------------------- the dataset


def split_of(record: WindowRecord, val_fraction: float) -> str:
    """The split ("val" or "train") of a record, fixed by a hash of its scene's id: the window id without the
    `_w{start}` suffix that windows cut from a longer scene carry, so those windows stay together."""
    key = record.scenario_id
    suffix = f"_w{record.window_start}"
    if key.endswith(suffix):
        key = key[: -len(suffix)]
    value = int.from_bytes(hashlib.sha256(key.encode()).digest()[:8], "little") / 2.0**64
    return "val" if value < val_fraction else "train"


class SceneDataset(Dataset):
    """Samples (`build_sample` dicts) of the windows of an InterDrive dataset folder, for a DataLoader
    with `collate_fn=collate_scenes`.

    `split` "train" / "val" keeps the windows `split_of` assigns there (`val_fraction` of the scenes,
    the same on every run and for every seed), "all" keeps every window. Scenario files are checked to
    exist up front and windows are read lazily (`load_window`); the last `cache_size` windows read are
    kept per process, which saves decoding when an upsampled window comes back.

    Item `i` is window `i % len(self)`, built with a generator seeded from (seed, epoch, i): the same
    item is the same sample within an epoch, and `set_epoch` changes every item's augmentation (call
    it before the epoch's DataLoader iterator is made; persistent workers keep their copy). Indices past
    `len(self)` let a sampler give repeated draws of one window their own augmentation (`MixingSampler`
    does). `augment` defaults to True for "train" and False otherwise. The dataset pickles without its
    cache, for DataLoader workers.
    """

    def __init__(
        self,
        labels_dir: str | Path,
        config: SampleConfig = SampleConfig(),
        *,
        split: str = "train",
        val_fraction: float = 0.1,
        seed: int = 0,
        augment: bool | None = None,
        cache_size: int = 8,
    ) -> None:
        if split not in ("train", "val", "all"):
            raise ValueError(f"split must be 'train', 'val' or 'all', got {split!r}")
        if not 0.0 <= val_fraction <= 1.0:
            raise ValueError(f"val_fraction must be in [0, 1], got {val_fraction}")
        self.labels_dir = Path(labels_dir)
        self.config = config
        self.split = split
        self.val_fraction = val_fraction
        self.seed = int(seed)
        self.augment = split == "train" if augment is None else bool(augment)
        self.cache_size = int(cache_size)
        self.epoch = 0
        records: list[WindowRecord] = []
        checked: set[str] = set()
        for shard, shard_records in iter_records(self.labels_dir):
            for rec in shard_records:
                if split != "all" and split_of(rec, val_fraction) != split:
                    continue
                if rec.source not in checked:
                    if not Path(rec.source).is_file():
                        raise InputError(
                            "scenario file not found (moved or deleted since the dataset was built?)",
                            path=rec.source,
                            where=f"labels shard {shard}",
                        )
                    checked.add(rec.source)
                records.append(rec)
        self.records: tuple[WindowRecord, ...] = tuple(records)
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

    def __getitem__(self, index: int) -> dict[str, Any]:
        pos = self._position(index)
        key = index if index >= 0 else pos
        rng = np.random.default_rng([self.seed, self.epoch, int(key)])
        return build_sample(self.window(pos), self.records[pos], self.config, rng, augment=self.augment)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_cache"] = OrderedDict()
        return state


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
