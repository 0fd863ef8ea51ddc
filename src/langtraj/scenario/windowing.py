"""Cutting long scenes into fixed windows (WOMD layout: 11 history + 80 future steps at 10 Hz). See docs/data.md."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from langtraj.errors import InputError
from langtraj.scenario.ids import cut_window_id
from langtraj.scenario.model import FUTURE_STEPS, HISTORY_STEPS, Scenario


@dataclass(frozen=True)
class WindowSpec:
    """Window layout: `history` steps up to and including the current one, then `future` steps.

    `stride` is the step offset between consecutive window starts (default: non-overlapping).
    """

    history: int = HISTORY_STEPS
    future: int = FUTURE_STEPS
    stride: int | None = None

    def __post_init__(self) -> None:
        if self.history < 1 or self.future < 0:
            raise ValueError(f"need history >= 1 and future >= 0, got {self.history}, {self.future}")
        if self.stride is not None and self.stride < 1:
            raise ValueError(f"stride must be >= 1, got {self.stride}")

    @property
    def length(self) -> int:
        return self.history + self.future

    @property
    def step(self) -> int:
        return self.stride or self.length


def window_starts(num_steps: int, spec: WindowSpec = WindowSpec()) -> list[int]:
    """Start steps of every full window that fits in a scene of `num_steps` steps."""
    return list(range(0, num_steps - spec.length + 1, spec.step))


def cut_window(scenario: Scenario, start: int, spec: WindowSpec = WindowSpec()) -> Scenario:
    """The window beginning at step `start`.

    Keeps agents with at least one valid step in the window (and the SDC always); tracks to predict
    and objects of interest stay only if still valid at the window's current step. The window's id
    is `scenario.ids.cut_window_id`; metadata records the parent scene and start step.
    """
    stop = start + spec.length
    if start < 0 or stop > scenario.num_steps:
        raise IndexError(f"window [{start}, {stop}) does not fit in {scenario.num_steps} steps")
    window = scenario.slice_steps(start, stop, current_index=spec.history - 1)
    valid = window.agents.valid
    keep = valid.any(axis=1)
    if window.sdc_index >= 0:
        keep[window.sdc_index] = True
    window = window.select_agents(np.flatnonzero(keep))
    agents = window.agents
    current_valid = agents.valid[:, window.current_index]
    ttp_keep = current_valid[agents.tracks_to_predict]
    agents = replace(
        agents,
        tracks_to_predict=agents.tracks_to_predict[ttp_keep],
        prediction_difficulty=agents.prediction_difficulty[ttp_keep],
        objects_of_interest=agents.objects_of_interest[current_valid[agents.objects_of_interest]],
    )
    return replace(
        window,
        scenario_id=cut_window_id(scenario.scenario_id, start),
        agents=agents,
        metadata={**window.metadata, "window": {"parent_id": scenario.scenario_id, "start": start}},
    )


def nth_window(scenario: Scenario, n: int, spec: WindowSpec = WindowSpec()) -> Scenario:
    """Window `n` of `scenario`, counted as `window_starts` lays them out; one that does not exist raises InputError
    (callers locate it: a file, a flag)."""
    starts = window_starts(scenario.num_steps, spec)
    if not 0 <= n < len(starts):
        raise InputError(
            f"window {n} does not exist: the scene has {scenario.num_steps} steps, "
            f"so {len(starts)} window(s) of {spec.length}"
        )
    return cut_window(scenario, starts[n], spec)


def iter_windows(scenario: Scenario, spec: WindowSpec = WindowSpec()) -> Iterator[Scenario]:
    """Every full window of `scenario`, in time order (none when the scene is shorter than one)."""
    for start in window_starts(scenario.num_steps, spec):
        yield cut_window(scenario, start, spec)
