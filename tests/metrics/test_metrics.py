"""Tests of fusion.metrics: TQI declaration lag and state changes, NEES and its interval."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import chi2

from fusion.metrics.localization import nees, nees_interval
from fusion.metrics.tqi import declaration_lag, state_changes
from fusion.passive.quality import TrackQuality, TrackQualityIndicator
from fusion.simulate.amplitudes import draw_amplitudes, draw_residuals


def test_declaration_lag_known_answers():
    """Lag counts from the onset to the first update in the state; never declared is inf."""
    L, U, W, S = (int(q) for q in TrackQuality)
    states = np.array([[S, S, S], [S, L, S], [U, S, S], [L, L, S], [L, L, S]])
    assert_allclose(declaration_lag(states, 1), [2.0, 0.0, np.inf])
    assert_allclose(declaration_lag(states, [0, 2, 0]), [3.0, 1.0, np.inf])  # lost before onset
    assert_allclose(declaration_lag(states[:, 0], 0, state=TrackQuality.UNCERTAIN), [2.0])


def test_declaration_lag_rejects_bad_onset():
    """An onset outside the updates is a ValueError naming it."""
    with pytest.raises(ValueError, match="onset must lie in"):
        declaration_lag(np.zeros((4, 2)), 4)


def test_state_changes_matches_the_tqi_history():
    """state_changes equals the TQI history's own n_changes on a noisy run."""
    rng = np.random.default_rng(4)
    snr = np.broadcast_to(rng.uniform(0.0, 12.0, 6), (300, 6))
    hist = TrackQualityIndicator().run(draw_amplitudes(snr, rng=rng), draw_residuals(snr, rng=rng))
    assert_allclose(state_changes(hist.state), hist.n_changes())
    assert state_changes([-1, -1, 3, 3, 2, 3]).tolist() == [2]  # the start is no change


def test_nees_known_answer_and_vectorised():
    """e^T P^-1 e by hand, and the batched form equals one solve per vector."""
    assert nees([1.0, 2.0], [[1.0, 0.0], [0.0, 4.0]]) == pytest.approx(2.0)
    rng = np.random.default_rng(1)
    a = rng.normal(size=(7, 3, 3))
    p = a @ a.transpose(0, 2, 1) + np.eye(3)
    e = rng.normal(size=(7, 3))
    assert_allclose(nees(e, p), [ei @ np.linalg.solve(pi, ei) for ei, pi in zip(e, p, strict=True)])
    with pytest.raises(ValueError, match="covariance must have shape"):
        nees(e, p[:, :2, :2])


def test_nees_of_consistent_errors_falls_in_the_interval_at_its_level():
    """Errors drawn from N(0, P): NEES averages d and 95 % of runs fall in nees_interval(d)."""
    rng = np.random.default_rng(2)
    d, n = 4, 20000
    a = rng.normal(size=(d, d))
    p = a @ a.T + 0.5 * np.eye(d)
    e = rng.multivariate_normal(np.zeros(d), p, size=n)
    v = nees(e, np.broadcast_to(p, (n, d, d)))
    assert v.mean() == pytest.approx(d, rel=0.03)
    lo, hi = nees_interval(d)
    assert np.mean((v >= lo) & (v <= hi)) == pytest.approx(0.95, abs=0.01)
    lo10, hi10 = nees_interval(d, n_runs=10, level=0.9)
    assert (lo10, hi10) == pytest.approx(tuple(chi2.ppf([0.05, 0.95], 40) / 10))
    means = v[: n // 10 * 10].reshape(-1, 10).mean(axis=1)
    assert np.mean((means >= lo10) & (means <= hi10)) == pytest.approx(0.90, abs=0.03)
