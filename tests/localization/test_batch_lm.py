"""The batched candidate solves of the competition against one GTSAM solve per candidate."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

import fusion.localization.competition as competition
from fusion.localization.batch_lm import solve_candidates
from fusion.localization.competition import _CandidateGraph, compete
from fusion.localization.surfaces import WindowTdoas
from fusion.simulate.tdoa_sets import simulate_tdoa_window

C = 1500.0
RING = np.array([[0.0, 0.0, -1600.0], [1433.0, 443.3, -1517.1], [-443.3, 1433.0, -1547.4],
                 [-1433.0, -443.3, -1660.3], [443.3, -1433.0, -1616.4]])


def _problem(rng: np.random.Generator, n_sensors: int):
    """A random array, its TDOAs of one source (1 us noise) and their sigmas."""
    s = rng.uniform(-3000.0, 3000.0, (n_sensors, 3))
    s[:, 2] = rng.uniform(-1800.0, -1500.0, n_sensors)
    pairs = np.array([(i, j) for i in range(n_sensors) for j in range(i + 1, n_sensors)])
    src = np.r_[rng.uniform(-2000.0, 2000.0, 2), rng.uniform(-1400.0, -200.0)]
    d = np.linalg.norm(src - s, axis=1)
    taus = (d[pairs[:, 0]] - d[pairs[:, 1]]) / C + rng.normal(0.0, 1e-6, len(pairs))
    sig = rng.uniform(5e-7, 2e-6, len(pairs))
    return WindowTdoas(s, pairs, taus, sig, c=C), src


@pytest.mark.parametrize("iterations", [3, 10, 100])
def test_batched_solves_match_one_gtsam_solve_per_candidate(iterations):
    """Random arrays, starts 1-300 m off, random weights: GTSAM's positions to a few um."""
    rng = np.random.default_rng(iterations)
    worst = 0.0
    for _ in range(25):
        t, src = _problem(rng, int(rng.integers(4, 9)))
        x0 = src + rng.normal(0.0, rng.choice([1.0, 30.0, 300.0]), (6, 3))
        w = rng.uniform(0.0, 1.0, (6, t.m)) ** 3
        graph = _CandidateGraph(t, iterations)
        ref = np.array([graph.solve(x0[k], w[k]) for k in range(6)])
        got = solve_candidates(x0, w, t.sensors, t.pairs, t.taus, t.sigmas, c=C,
                               max_iterations=iterations)
        worst = max(worst, float(np.abs(got - ref).max()))
    # the TDOA sigmas are 0.5-2 us, 0.75-3 mm of range: the two agree 1,000 times closer
    assert worst < 1e-5


def test_batched_solve_keeps_the_iteration_limit():
    """With one iteration from 300 m off, both stop short of the source at the same point."""
    rng = np.random.default_rng(7)
    t, src = _problem(rng, 6)
    x0 = src + np.array([[300.0, -200.0, 150.0]])
    w = np.ones((1, t.m))
    one = solve_candidates(x0, w, t.sensors, t.pairs, t.taus, t.sigmas, c=C, max_iterations=1)
    ref = _CandidateGraph(t, 1).solve(x0[0], w[0])
    assert_allclose(one[0], ref, atol=1e-6)
    assert np.linalg.norm(one[0] - src) > 1.0  # not converged after one step


def test_zero_weights_and_an_exact_start_stay_put():
    """A candidate with no weight (zero cost) and one at its exact solution do not move."""
    rng = np.random.default_rng(3)
    t, src = _problem(rng, 5)
    exact = WindowTdoas(t.sensors, t.pairs, t.predicted(src), t.sigmas, c=C)  # no noise
    x0 = np.vstack([src + 50.0, src])
    w = np.vstack([np.zeros(t.m), np.ones(t.m)])
    got = solve_candidates(x0, w, exact.sensors, exact.pairs, exact.taus, exact.sigmas, c=C,
                           max_iterations=10)
    assert_allclose(got[0], x0[0], atol=0.0)
    assert_allclose(got[1], src, atol=1e-9)


def test_the_competition_solves_its_candidates_together(monkeypatch):
    """compete's candidate update goes through solve_candidates, several candidates per call,
    and finds the source (a test that fails if the batched solve is taken out)."""
    truth = np.array([100.0, 200.0, -800.0])
    w = simulate_tdoa_window(RING, [truth], c=C, seed=6, noise_range_s=(20e-6, 20e-6))
    t = WindowTdoas(RING, w.pairs, w.taus, np.full(10, 20e-6), c=C, alpha=w.alpha)
    sizes = []
    real = competition.solve_candidates

    def counted(x0, *args, **kwargs):
        sizes.append(len(x0))
        return real(x0, *args, **kwargs)

    monkeypatch.setattr(competition, "solve_candidates", counted)
    res = compete(t, np.array([truth + 5.0, truth - 8.0, truth + [20.0, 0, 0]]),
                  start_scale_s=5e-3)
    assert sizes and max(sizes) >= 2
    assert np.linalg.norm(res.positions[0] - truth) < 1.0
