"""The experiments' extension point: an `Experiment` is one table of docs/experiments.md, its settings a
dataclass read from a YAML file under `configs/experiments/` or from `langtraj experiment NAME`'s flags
(docs/experiments.md, 'Experiment configs')."""

from __future__ import annotations

from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any, ClassVar

from langtraj.errors import InputError
from langtraj.experiments.common import write_results
from langtraj.registry import Registry
from langtraj.settings import build_dataclass, load_dataclass, read_yaml


class Experiment(ABC):
    """One experiment: `name` (its verb and the YAML's `experiment:`), its `settings` dataclass (with a `json`
    path, None for none), and `tables`, which prints its tables and returns every figure."""

    name: ClassVar[str]
    settings: ClassVar[type]

    @abstractmethod
    def tables(self, settings: Any) -> dict[str, Any]:
        """Run the experiment with `settings` (an instance of `self.settings`), print its tables, return every
        figure."""

    def run(self, settings: Any) -> dict[str, Any]:
        """`tables`, with every figure also written to `settings.json` when it is given."""
        results = self.tables(settings)
        write_results(settings.json, results)
        return results


EXPERIMENTS: Registry[Experiment] = Registry("experiment")
"""The experiments by name; the package (`langtraj.experiments`) registers the built-in ones on import."""


def experiment_settings(name: str, config: str | Path | None, given: dict[str, Any]) -> Any:
    """The settings of experiment `name`: the YAML file `config` (whose `experiment:` must be `name`), if any,
    with the `given` command-line values over it; errors name the file and key."""
    experiment = EXPERIMENTS.get(name)
    if config is None:
        try:
            return build_dataclass(experiment.settings, given)
        except InputError as exc:
            raise exc.located(where="flags (or --config FILE)") from None
    data = read_yaml(config)
    declared = data.pop("experiment", name)
    if declared != name:
        raise InputError(f"this file configures {declared!r}, not {name!r}", path=config, where="experiment")
    return load_dataclass(experiment.settings, config, {**data, **given})
