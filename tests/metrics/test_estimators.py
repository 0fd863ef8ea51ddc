"""Histogram and Bernoulli likelihood estimators against probabilities worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from langtraj.metrics.estimators import BernoulliEstimator, HistogramEstimator

TWO_BINS = HistogramEstimator(0.0, 2.0, 2, pseudocount=0.1)  # bins [0, 1) and [1, 2]


def test_histogram_with_pseudocount() -> None:
    sim = np.array([[0.5, 0.5, 0.5, 1.5]])  # counts 3 and 1, +0.1 each -> 3.1 / 4.2 and 1.1 / 4.2
    got = TWO_BINS.log_prob(np.array([[0.2, 1.7, 0.0]]), sim)
    np.testing.assert_allclose(got, [[math.log(3.1 / 4.2), math.log(1.1 / 4.2), math.log(3.1 / 4.2)]], rtol=1e-12)


def test_histogram_edges_clipping_and_nan() -> None:
    sim = np.array([[0.5, 0.5, 0.5, 1.5]])
    low, high = math.log(3.1 / 4.2), math.log(1.1 / 4.2)
    # Below the range -> first bin; above it, exactly the maximum, an inner edge and NaN -> last bin.
    got = TWO_BINS.log_prob(np.array([[-5.0, 10.0, 2.0, 1.0, np.nan]]), sim)
    np.testing.assert_allclose(got, [[low, high, high, high, high]], rtol=1e-12)


def test_histogram_clips_and_bins_simulated_values_the_same_way() -> None:
    sim = np.array([[-3.0, 7.0, np.nan, 2.0]])  # bins 0, 1, 1, 1 -> counts 1.1 and 3.1 of 4.2
    got = TWO_BINS.log_prob(np.array([[0.3, 1.3]]), sim)
    np.testing.assert_allclose(got, [[math.log(1.1 / 4.2), math.log(3.1 / 4.2)]], rtol=1e-12)


def test_histogram_populations_are_independent() -> None:
    est = HistogramEstimator(-1.0, 1.0, 4, pseudocount=0.5)  # bins of width 0.5
    sim = np.array([[-0.9, -0.9, -0.9, -0.9], [0.9, 0.9, 0.1, -0.1]])
    log = np.array([[-0.8, 0.8], [0.8, -0.8]])
    # Row 0: counts [4, 0, 0, 0] + 0.5 over 6. Row 1: counts [0, 1, 1, 2] + 0.5 over 6.
    expected = np.log([[4.5 / 6, 0.5 / 6], [2.5 / 6, 0.5 / 6]])
    np.testing.assert_allclose(est.log_prob(log, sim), expected, rtol=1e-12)


def test_histogram_probabilities_sum_to_one() -> None:
    est = HistogramEstimator(-12.0, 12.0, 11)
    rng = np.random.default_rng(0)
    sim = rng.normal(0, 6, (3, 50))
    centres = -12.0 + (np.arange(11) + 0.5) * 24.0 / 11
    probs = np.exp(est.log_prob(np.broadcast_to(centres, (3, 11)), sim))
    np.testing.assert_allclose(probs.sum(axis=1), 1.0, rtol=1e-12)


@pytest.mark.parametrize("n", [1, 4, 32])
def test_bernoulli_all_true(n: int) -> None:
    est = BernoulliEstimator(pseudocount=0.001)
    sim = np.ones((1, n), bool)
    got = est.log_prob(np.array([[True, False]]), sim)
    expected = [[math.log((n + 0.001) / (n + 0.002)), math.log(0.001 / (n + 0.002))]]
    np.testing.assert_allclose(got, expected, rtol=1e-9)


def test_bernoulli_mixed_and_batched() -> None:
    est = BernoulliEstimator()
    sim = np.array([[True, True, True, False, False], [False] * 5])
    got = est.log_prob(np.array([[True], [False]]), sim)
    np.testing.assert_allclose(got, [[math.log(3.001 / 5.002)], [math.log(5.001 / 5.002)]], rtol=1e-9)
