"""Delay-track internals: candidate subsets, the consensus shortcut, the nested least squares."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.clicks import _consensus, delaytrack
from fusion.clicks.delaytrack import consensus_inliers, fit_delays


@pytest.mark.parametrize(("n", "k"), [(3, 1), (7, 2), (12, 3), (34, 3), (95, 2)])
def test_subsets_are_the_thinned_lexicographic_combinations(n, k):
    """Unranked subsets equal itertools.combinations thinned at linspace positions."""
    ref = np.array(list(combinations(range(n), k)), dtype=np.int64)
    if ref.shape[0] > 4000:
        ref = ref[np.linspace(0, ref.shape[0] - 1, 4000).astype(np.int64)]
    assert np.array_equal(_consensus.subsets(n, k, 4000), ref)


def _track(rng, n, *, n_bad, sig=1e-6, curve=2e-7):
    t = np.sort(rng.uniform(0.0, 11.0, n))
    s = np.full(n, sig) * rng.uniform(0.7, 1.5, n)
    d = 0.3 + 8e-4 * (t - 5.0) + curve * (t - 5.0) ** 2 + s * rng.standard_normal(n)
    bad = rng.choice(n, n_bad, replace=False)
    d[bad] += rng.choice([-1.0, 1.0], n_bad) * rng.uniform(6.0, 40.0, n_bad) * s[bad]
    return t, d, s


@pytest.mark.parametrize("seed", range(40))
def test_shortcut_gives_the_search_result(seed, monkeypatch):
    """The certified least-squares shortcut returns what the full MSAC search returns."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(6, 34))
    t, d, s = _track(rng, n, n_bad=int(rng.integers(0, max(1, n // 5) + 1)))
    kw = {} if seed % 2 else {"max_rate": np.inf, "max_accel": np.inf}
    fast = consensus_inliers(t, d, s, **kw)
    monkeypatch.setattr(delaytrack, "trimmed_consensus", lambda *a, **k: None)
    assert np.array_equal(fast, consensus_inliers(t, d, s, **kw))


def test_shortcut_declines_a_tight_track_with_one_stray_click(monkeypatch):
    """Seven clicks on a curve to 0.05 sigma and one 6 sigma off: the search (which drops the
    stray click, though a fit through all eight stays within 4 sigma) decides, not the shortcut."""
    t = np.array([0.0, 0.574, 1.166, 1.655, 2.211, 2.69, 3.209, 3.754])
    s = np.full(8, 7.5e-5)
    d = 0.1 + 2e-3 * t + 1e-4 * t**2
    d[-1] += 6.3 * s[-1]
    keep = consensus_inliers(t, d, s, max_rate=np.inf, max_accel=np.inf)
    assert np.array_equal(np.flatnonzero(~keep), [7])
    u = t - t.mean()
    ps = u[:, None] ** np.arange(3) / s[:, None]
    assert _consensus.trimmed_consensus(ps, d / s, 4.0, np.inf, np.inf, 1) is None


def test_fit_delays_matches_numpy_polyfit():
    """Coefficients, covariance and chi-square of the chosen degree equal numpy's weighted fit."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 12.0, 30)
    sig = rng.uniform(0.5, 2.0, 30) * 1e-6
    d = 0.2 + 1e-3 * (t - 6) + 4e-7 * (t - 6) ** 2 + sig * rng.standard_normal(30)
    coef, cov, t_ref, birge = fit_delays(t, d, sig, max_degree=2)
    assert coef.size == 3
    p, c = np.polyfit(t - t_ref, d, 2, w=1.0 / sig, cov="unscaled")
    assert_allclose(coef, p[::-1], rtol=1e-9, atol=1e-15)
    assert_allclose(cov, c[::-1, ::-1], rtol=1e-8)
    res = (d - np.polyval(p, t - t_ref)) / sig
    assert_allclose(birge, np.sqrt(res @ res / 27), rtol=1e-9)
