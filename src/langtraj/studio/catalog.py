"""The scenes the studio offers: every scenario of the files and folders it was started with, each long scene
(more than one standard window) listed once per window, with a short opaque key per entry; files that fail to
load are listed with their one-line error (docs/studio.md, 'Scenes')."""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from langtraj.errors import InputError
from langtraj.roads import MapIndex
from langtraj.rollouts.agents import sim_agent_indices
from langtraj.scenario.io import expand_scenario_paths, read_scenario, read_scenarios
from langtraj.scenario.model import WINDOW_STEPS, Scenario
from langtraj.scenario.windowing import cut_window, nth_window, window_starts

CACHED_SCENES = 8
"""Scenes (with their map index) kept in memory; the others are read again from their file when asked for."""

_DATASETS = {"waymo": "womd"}
"""Dataset names of ScenarioNet's metadata spelled as the studio's kinds."""


@dataclass(frozen=True)
class SceneEntry:
    """One scene of the catalog: `index` in `file`, `window` (the standard window's number, None for a scene
    of one window), its id and map `kind`, its agents and sim agents (valid at the current step) and steps."""

    key: str
    file: Path
    index: int
    window: int | None
    scenario_id: str
    kind: str
    agents: int
    sim_agents: int
    steps: int

    def to_json(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "scenario_id": self.scenario_id,
            "file": str(self.file),
            "index": self.index,
            "window": self.window,
            "kind": self.kind,
            "agents": self.agents,
            "sim_agents": self.sim_agents,
            "steps": self.steps,
        }

    def matches(self, q: str | None, kind: str | None, min_agents: int | None, max_agents: int | None) -> bool:
        """Whether the entry passes the scene list's filters: `q` a case-insensitive substring of the scenario id
        or file name, `kind` the map kind, and the bounds on its agent count."""
        if q and q.lower() not in self.scenario_id.lower() and q.lower() not in self.file.name.lower():
            return False
        if kind and kind.lower() != self.kind.lower():
            return False
        if min_agents is not None and self.agents < min_agents:
            return False
        return max_agents is None or self.agents <= max_agents


@dataclass(frozen=True)
class FileError:
    """A file the catalog could not read, with its one-line error."""

    file: str
    error: str

    def to_json(self) -> dict[str, str]:
        return {"file": self.file, "error": self.error}


@dataclass(frozen=True)
class LoadedScene:
    """A scene in memory with the map index its prompt checks share."""

    entry: SceneEntry
    scenario: Scenario
    map_index: MapIndex


def scene_kind(scenario: Scenario) -> str:
    """The map kind of a scene: a synthesized window's network kind (its metadata's `kind`), else the dataset a
    ScenarioNet file names (nuscenes, womd, ...), else the file format."""
    meta = scenario.metadata or {}
    if isinstance(meta.get("kind"), str):
        return meta["kind"]
    source = (meta.get("scenarionet") or {}).get("source_metadata") if isinstance(meta, dict) else None
    dataset = source.get("dataset") if isinstance(source, dict) else None
    if isinstance(dataset, str) and dataset:
        return _DATASETS.get(dataset.lower(), dataset.lower())
    return scenario.source_format or "unknown"


def _windows(scenario: Scenario) -> list[tuple[int | None, Scenario]]:
    """(window number, scene) for each standard window of a long scene; the scene itself when it is one window."""
    if scenario.num_steps <= WINDOW_STEPS:
        return [(None, scenario)]
    return [(n, cut_window(scenario, start)) for n, start in enumerate(window_starts(scenario.num_steps))]


class Catalog:
    """The scene list (`entries`, in the order of the files; each keyed by `scene_key`) and the files that failed
    (`errors`)."""

    def __init__(self, entries: Sequence[SceneEntry], errors: Sequence[FileError]):
        self.entries = tuple(entries)
        self.errors = tuple(errors)
        self._by_key = {e.key: e for e in self.entries}
        self._cache: OrderedDict[str, LoadedScene] = OrderedDict()
        self._lock = threading.Lock()

    @classmethod
    def build(cls, paths: Iterable[str | Path]) -> Catalog:
        """Read every scenario of `paths` (files, and folders searched recursively)."""
        entries: list[SceneEntry] = []
        errors: list[FileError] = []
        files: list[Path] = []
        seen: set[str] = set()
        for path in paths:
            try:
                files += expand_scenario_paths([path])
            except InputError as exc:
                errors.append(FileError(str(path), str(exc)))
        for file in files:
            try:
                for index, scenario in enumerate(read_scenarios(file)):
                    for window, scene in _windows(scenario):
                        key = scene_key(file, index, window)
                        if key not in seen:  # a file named twice is listed once
                            seen.add(key)
                            entries.append(_entry(key, file, index, window, scene))
            except InputError as exc:
                errors.append(FileError(str(file), str(exc)))
            except (OSError, ValueError) as exc:  # a file the readers refuse in another way: listed, not fatal
                errors.append(FileError(str(file), f"{file}: {exc}"))
        return cls(entries, errors)

    def entry(self, key: str) -> SceneEntry | None:
        return self._by_key.get(key)

    def search(
        self,
        q: str | None = None,
        kind: str | None = None,
        min_agents: int | None = None,
        max_agents: int | None = None,
    ) -> list[SceneEntry]:
        return [e for e in self.entries if e.matches(q, kind, min_agents, max_agents)]

    def load(self, key: str) -> LoadedScene | None:
        """The scene of `key` (read again from its file unless cached), or None for an unknown key."""
        entry = self._by_key.get(key)
        if entry is None:
            return None
        with self._lock:
            if key in self._cache:
                self._cache.move_to_end(key)
                return self._cache[key]
        scenario = read_entry(entry)
        loaded = LoadedScene(entry, scenario, MapIndex.build(scenario.road_map))
        with self._lock:
            self._cache[key] = loaded
            while len(self._cache) > CACHED_SCENES:
                self._cache.popitem(last=False)
        return loaded


def scene_key(file: Path, index: int, window: int | None) -> str:
    """A scene's key: short, url-safe and the same for the same scene whatever else the studio lists, so the jobs a
    studio kept name their scenes again after a restart with other files."""
    digest = hashlib.sha1(f"{Path(file).resolve()}#{index}#{window}".encode()).hexdigest()
    return f"s{digest[:12]}"


def read_entry(entry: SceneEntry) -> Scenario:
    """The scene of a catalog entry, read from its file (its window cut)."""
    scenario = read_scenario(entry.file, entry.index)
    if entry.window is None:
        return scenario
    return nth_window(scenario, entry.window)


def _entry(key: str, file: Path, index: int, window: int | None, scene: Scenario) -> SceneEntry:
    return SceneEntry(
        key=key,
        file=file,
        index=index,
        window=window,
        scenario_id=scene.scenario_id,
        kind=scene_kind(scene),
        agents=scene.num_agents,
        sim_agents=len(sim_agent_indices(scene)),
        steps=scene.num_steps,
    )
