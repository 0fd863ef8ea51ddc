"""Likelihood estimators: how probable the logged value is under the distribution of simulated values.

Each estimator takes `log` [B, n] and `sim` [B, m] (B independent populations) and returns the log
probability of every logged value, [B, n]. The histogram estimator is WOSAC's: values clipped to the
range, equal-width bins, additive smoothing; NaN counts in the last bin (as in the official code).

See docs/metrics.md.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np


class Estimator(ABC):
    """A density estimate from simulated samples, scored at the logged samples."""

    name: ClassVar[str]

    @abstractmethod
    def log_prob(self, log: np.ndarray, sim: np.ndarray) -> np.ndarray:
        """Log probability [B, n] of `log` [B, n] under the distribution of `sim` [B, m]."""


def _bin_index(values: np.ndarray, low: float, high: float, num_bins: int) -> np.ndarray:
    """Bin of each value for `num_bins` equal bins over [low, high]; the top edge and NaN go to the last."""
    clipped = np.clip(values, low, high)
    edges = np.linspace(low, high, num_bins + 1).astype(np.float32)
    index = np.searchsorted(edges, clipped.astype(np.float32), side="right") - 1
    index = np.where(np.isnan(values), num_bins - 1, index)
    return np.clip(index, 0, num_bins - 1)


@dataclass(frozen=True)
class HistogramEstimator(Estimator):
    """Equal-width histogram over [min_val, max_val] with `pseudocount` added to every bin."""

    name: ClassVar[str] = "histogram"
    min_val: float
    max_val: float
    num_bins: int
    pseudocount: float = 0.1

    def log_prob(self, log: np.ndarray, sim: np.ndarray) -> np.ndarray:
        batch = sim.shape[0]
        sim_bins = _bin_index(sim, self.min_val, self.max_val, self.num_bins)
        counts = np.zeros((batch, self.num_bins), np.float64)
        np.add.at(counts, (np.arange(batch)[:, None], sim_bins), 1.0)
        counts += self.pseudocount
        log_probs = np.log(counts / counts.sum(axis=1, keepdims=True))
        log_bins = _bin_index(log, self.min_val, self.max_val, self.num_bins)
        return np.take_along_axis(log_probs, log_bins, axis=1)


@dataclass(frozen=True)
class BernoulliEstimator(Estimator):
    """Probability of a boolean outcome: a two-bin histogram with `pseudocount` smoothing."""

    name: ClassVar[str] = "bernoulli"
    pseudocount: float = 0.001

    def log_prob(self, log: np.ndarray, sim: np.ndarray) -> np.ndarray:
        two_bins = HistogramEstimator(-0.5, 1.5, 2, self.pseudocount)
        return two_bins.log_prob(np.asarray(log, np.float32), np.asarray(sim, np.float32))
