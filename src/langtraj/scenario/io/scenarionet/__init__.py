"""ScenarioNet / MetaDrive "scenario description" pickles: one scenario per file, loaded safely.

A ScenarioNet file is a pickled dict of dicts of numpy arrays ('tracks', 'map_features',
'dynamic_map_states', 'metadata'). Pickle can run code when loaded, so files are read with an
unpickler that admits numpy arrays and builtin containers and nothing else; the
`collections.defaultdict` (with a builtin default factory) and `collections.OrderedDict` that real
ScenarioNet files hold are rebuilt as plain dicts. docs/data.md describes the format and what is kept.

`scenario_from_dict` / `scenario_to_dict` map between that layout and our `Scenario`. Track and map
keys that are not all decimal integers (nuScenes tokens, UUIDs) are numbered 0..n-1 in file order and
kept, with type strings our enums do not hold (TRAFFIC_CONE, ...), under
`scenario.metadata["scenarionet"]`, so that reading then writing restores them. Events and other
metadata of our own travel in the pickle's `metadata["langtraj"]`.

Not kept: lane 'width' arrays, per-track metadata (nuScenes' fine-grained categories) and
'object_summary'. Map points are written as float64 [N, 3]. Under numpy 2 the written pickles name
`numpy._core`, which numpy >= 1.26.1 can load.

The package: `common` (constants, type tables), `unpickling` (safe loading), `reader` (dict -> model),
`writer` (model -> dict); the registered format is defined here.
"""

from __future__ import annotations

import itertools
import pickle
from collections.abc import Iterable, Iterator
from pathlib import Path

from langtraj.errors import InputError
from langtraj.fileio import atomic_open
from langtraj.scenario.io.base import ScenarioFormat, register_format
from langtraj.scenario.io.scenarionet.common import FORMAT_NAME, PICKLE_PROTOCOL
from langtraj.scenario.io.scenarionet.reader import scenario_from_dict
from langtraj.scenario.io.scenarionet.unpickling import load_pickle, looks_like_scenarionet
from langtraj.scenario.io.scenarionet.writer import scenario_to_dict
from langtraj.scenario.model import Scenario

# ---------------------------------------------------------------------------- the format


@register_format
class ScenarioNetFormat(ScenarioFormat):
    """ScenarioNet / MetaDrive scenario description pickles (exactly one scenario per file)."""

    name = FORMAT_NAME
    suffixes = (".pkl", ".pickle")

    @classmethod
    def sniff(cls, head: bytes) -> bool:
        return looks_like_scenarionet(head)

    def read(self, path: Path) -> Iterator[Scenario]:
        path = Path(path)
        yield scenario_from_dict(load_pickle(path), where=str(path))

    def write(self, path: Path, scenarios: Iterable[Scenario], *, compress: bool = False) -> int:
        first_two = list(itertools.islice(scenarios, 2))
        if len(first_two) != 1:
            count = "none" if not first_two else "more than one"
            raise InputError(f"a ScenarioNet file holds exactly one scenario; got {count}", path=path)
        data = scenario_to_dict(first_two[0])
        with atomic_open(path, "wb", compress=compress) as fh:
            pickle.dump(data, fh, protocol=PICKLE_PROTOCOL)
        return 1


__all__ = [
    "ScenarioNetFormat",
    "load_pickle",
    "looks_like_scenarionet",
    "scenario_from_dict",
    "scenario_to_dict",
]
