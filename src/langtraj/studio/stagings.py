"""What a scene of the catalog can stage against an ego, for the page's list (docs/studio.md, 'GET
/api/scenes/{key}/stagings'): `interdrive.suggest.suggest_stagings`, the search `langtraj suggest` runs, over the
catalog's loaded scene and its cached map index. The last few answers are kept, since the page asks again each time
a scene or an ego is picked again and a search takes a second or more."""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Sequence
from typing import Any

from langtraj.env.environment import ego_row
from langtraj.errors import InputError
from langtraj.interdrive.behaviour import Behaviour
from langtraj.interdrive.suggest import Staging, parse_behaviour, suggest_stagings
from langtraj.studio.catalog import LoadedScene

CACHED_ANSWERS = 32
"""(scene, ego, behaviours) answers kept in memory; the oldest is searched again when asked for."""

_Key = tuple[str, int, tuple[Behaviour, ...] | None]


def staging_json(staging: Staging) -> dict[str, Any]:
    """A staging as the page gets it: its own JSON (`Staging.to_json`, as `langtraj suggest --json` prints it) and
    `typed_prompt`, the prompt with the ego's `@id` in place of `@ego`, as the page's prompt boxes name agents."""
    return staging.to_json() | {"typed_prompt": staging.typed_prompt}


def behaviours_of(names: Sequence[str]) -> tuple[Behaviour, ...] | None:
    """The pair behaviours `names` name (`parse_behaviour`: "cut-in" reads as cut_in), None for every one;
    InputError at `behaviour` for a name that is not one."""
    try:
        return tuple(dict.fromkeys(parse_behaviour(name) for name in names)) or None
    except InputError as exc:
        raise exc.located(where="behaviour") from None


def default_ego(loaded: LoadedScene) -> int:
    """The ego the studio's planner drives in the scene (`env.environment.ego_row`: the self-driving car, else its
    most important vehicle), so the list a scene opens with stages against the agent a job's planner drives."""
    scenario = loaded.scenario
    return int(scenario.agents.ids[ego_row(scenario)])


class StagingLists:
    """The stagings of loaded scenes, searched on demand and the last `size` answers kept (thread-safe: the
    app answers requests from its thread pool)."""

    def __init__(self, size: int = CACHED_ANSWERS):
        self._size = size
        self._kept: OrderedDict[_Key, tuple[Staging, ...]] = OrderedDict()
        self._lock = threading.Lock()

    def find(
        self, loaded: LoadedScene, ego: int | None, behaviours: tuple[Behaviour, ...] | None = None
    ) -> tuple[int, tuple[Staging, ...]]:
        """(the ego, the stagings of `behaviours` toward it, most natural first) in `loaded`: `ego` (InputError where
        the scene has no such agent valid at its current step) or, when None, the planner's (`default_ego`). The
        stagings are labelled with the scene's file, index and window, as a suite's case names them."""
        ego = default_ego(loaded) if ego is None else ego
        key = (loaded.entry.key, ego, behaviours)
        with self._lock:
            if key in self._kept:
                self._kept.move_to_end(key)
                return ego, self._kept[key]
        entry = loaded.entry
        found = suggest_stagings(
            loaded.scenario, ego=ego, behaviours=behaviours, map_index=loaded.map_index,
            scene=str(entry.file), index=entry.index, window=entry.window,
        )  # fmt: skip
        with self._lock:
            self._kept[key] = found
            while len(self._kept) > self._size:
                self._kept.popitem(last=False)
        return ego, found
