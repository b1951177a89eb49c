"""Tests of TDOA association by click matching (eq. 12-13) and of the triangle closure check."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from fusion.clicks.associate import (
    TdoaClicks,
    TimeAssociator,
    click_match,
    closure_check,
    cross_pair_alpha,
)

SIG = 1e-3


def brute_match(p, q, sigma):
    """Eq. (12) as the full double sum."""
    d = np.subtract.outer(np.asarray(p, float), np.asarray(q, float))
    return float(np.exp(-0.5 * (d / sigma) ** 2).sum())


def emissions(n, seed, *, t0=0.0):
    """Irregular click emission times (no periodic coincidences), s."""
    rng = np.random.default_rng(seed)
    return t0 + np.cumsum(rng.uniform(0.25, 0.6, n))


def geometric_tdoas(delays, emit, pairs, *, sigma_s=None):
    """TDOAs of one source: sensor k hears a click emitted at e at e + delays[k]."""
    out = []
    for i, j in pairs:
        out.append(TdoaClicks((i, j), delays[i] - delays[j], emit + delays[i], sigma_s))
    return out


class TestClickMatch:
    def test_identical_lists_count_clicks(self):
        """Identical lists of n well-separated clicks give beta = n."""
        t = emissions(25, 0)
        assert_allclose(click_match(t, t, SIG), 25.0, atol=1e-9)

    def test_disjoint_lists_give_zero(self):
        """Lists whose clicks are 50 ms apart give beta ~ 0."""
        t = np.arange(20) * 0.4
        assert click_match(t, t + 0.05, SIG) < 1e-12

    def test_single_offset_known_answer(self):
        """One pair offset by d adds exp(-d^2 / (2 sigma^2))."""
        assert_allclose(click_match([1.0], [1.0015], SIG), np.exp(-0.5 * 1.5**2), rtol=1e-12)

    def test_equals_full_double_sum(self):
        """The windowed sum equals the full double sum (dense random clicks, any order)."""
        rng = np.random.default_rng(1)
        p, q = rng.uniform(0, 2, 400), rng.uniform(0, 2, 300)
        assert_allclose(click_match(p, q, 5e-3), brute_match(p, q, 5e-3), rtol=1e-7)

    def test_long_lists_are_linear(self):
        """10^5 clicks against themselves (10^10 pairs if done densely) count 10^5 at once."""
        t = np.arange(100_000) * 0.37
        assert_allclose(click_match(t, t[::-1], SIG), 100_000, rtol=1e-12)

    def test_empty_and_bad_input(self):
        """Empty lists give 0; a bad sigma or non-finite time raises ValueError."""
        assert click_match([], [1.0, 2.0], SIG) == 0.0
        with pytest.raises(ValueError, match="sigma_t"):
            click_match([1.0], [1.0], 0.0)
        with pytest.raises(ValueError, match="finite"):
            click_match([np.nan], [1.0], SIG)

    @settings(max_examples=60, deadline=None)
    @given(
        st.lists(st.floats(0, 10, allow_nan=False), max_size=40),
        st.lists(st.floats(0, 10, allow_nan=False), max_size=40),
        st.floats(1e-4, 0.5),
    )
    def test_symmetric(self, p, q, sigma):
        """click_match(p, q) == click_match(q, p)."""
        assert_allclose(click_match(p, q, sigma), click_match(q, p, sigma), rtol=1e-12, atol=1e-300)


class TestTimeAssociation:
    def test_links_right_pairs(self):
        """Two whales on pair (0, 1) and one on (0, 2) each link to their own previous TDOA."""
        e1, e2 = emissions(40, 1), emissions(40, 2)
        prev = [TdoaClicks((0, 1), 0.100, e1[:30]), TdoaClicks((0, 1), -0.800, e2[:30]),
                TdoaClicks((0, 2), 0.300, e1[:30])]
        # current window: slid by 2 s (some clicks new), small drift, listed in another order
        cur = [TdoaClicks((0, 2), 0.3012, e1[5:35] + 5e-4), TdoaClicks((0, 1), -0.8005, e2[5:35]),
               TdoaClicks((0, 1), 0.1008, e1[5:35] + 4e-4)]
        res = TimeAssociator().associate(prev, cur)
        assert [(k.previous, k.current) for k in res.links] == [(2, 0), (1, 1), (0, 2)]
        assert res.confirmed.all() and res.previous_linked.all()
        assert_allclose([k.dtau_s for k in res.links], [1.2e-3, -5e-4, 8e-4], atol=1e-12)
        assert res.links[0].beta > 20
        assert res.beta[0, 0] == 0 and np.isnan(res.dtau_s[0, 0])  # different pairs never compared

    def test_rejects_jump_over_3ms(self):
        """Matching clicks but a 3.5 ms TDOA jump (2 s update) is not linked; 2.5 ms is."""
        e = emissions(30, 3)
        prev = [TdoaClicks((1, 2), 0.2, e)]
        assoc = TimeAssociator()
        assert not assoc.associate(prev, [TdoaClicks((1, 2), 0.2035, e)]).confirmed[0]
        assert assoc.associate(prev, [TdoaClicks((1, 2), 0.2025, e)]).confirmed[0]

    def test_max_dtau_scales_with_update_period(self):
        """The 3 ms gate at 2 s becomes 6 ms at a 4 s update; an explicit value overrides."""
        assert TimeAssociator(update_period_s=4.0).max_dtau_s == pytest.approx(6e-3)
        assert TimeAssociator(update_period_s=4.0, max_dtau_s=1e-3).max_dtau_s == 1e-3
        e = emissions(30, 4)
        res = TimeAssociator(update_period_s=4.0).associate([TdoaClicks((0, 1), 0.2, e)],
                                                           [TdoaClicks((0, 1), 0.2045, e)])
        assert res.confirmed[0]

    def test_needs_beta_above_seven(self):
        """Six shared clicks (beta ~ 6) do not link; eight do."""
        e = emissions(30, 5)
        prev = [TdoaClicks((0, 1), 0.2, e[:6])]
        assert not TimeAssociator().associate(prev, [TdoaClicks((0, 1), 0.2, e)]).confirmed[0]
        prev = [TdoaClicks((0, 1), 0.2, e[:8])]
        assert TimeAssociator().associate(prev, [TdoaClicks((0, 1), 0.2, e)]).confirmed[0]

    def test_reversed_orientation(self):
        """A previous TDOA on (j, i) is compared as -tau with its clicks moved to sensor i."""
        e = emissions(30, 6)
        cur = TdoaClicks((0, 1), 0.4, e)
        res = TimeAssociator().associate([cur.reversed()], [TdoaClicks((0, 1), 0.4005, e)])
        assert res.confirmed[0]
        assert_allclose(res.links[0].dtau_s, 5e-4, atol=1e-12)
        assert res.links[0].beta == pytest.approx(30, abs=1e-6)

    def test_one_to_one(self):
        """Two current TDOAs that both match one previous TDOA: only the better one links."""
        e = emissions(30, 7)
        prev = [TdoaClicks((0, 1), 0.2, e)]
        cur = [TdoaClicks((0, 1), 0.2, e[:15]), TdoaClicks((0, 1), 0.2, e)]
        res = TimeAssociator().associate(prev, cur)
        assert [(k.previous, k.current) for k in res.links] == [(0, 1)]
        assert res.confirmed.tolist() == [False, True]

    def test_empty_windows(self):
        """No TDOAs in a window: no links, empty arrays of the right shape."""
        res = TimeAssociator().associate([], [TdoaClicks((0, 1), 0.1, [1.0])])
        assert res.links == () and res.beta.shape == (0, 1) and res.confirmed.tolist() == [False]


class TestCrossPairAlpha:
    def test_reference_shift_sign(self):
        """On a 3-sensor geometry, referring clicks by t_j = t_i - tau makes alpha ~ n."""
        emit = emissions(20, 8)
        delays = np.array([1.2, 0.7, 1.9])
        pairs = [(0, 1), (1, 2), (2, 0), (1, 0)]
        tdoas = geometric_tdoas(delays, emit, pairs)
        alpha = cross_pair_alpha(tdoas, sigma_t_s=SIG)
        assert_allclose(alpha[0, 1], 20, atol=1e-6)  # (0,1)&(1,2): share 1 -> (0,1) shifted by -tau
        assert_allclose(alpha[0, 2], 20, atol=1e-6)  # (0,1)&(2,0): share 0 -> (2,0) shifted
        assert_allclose(alpha[1, 2], 20, atol=1e-6)  # (1,2)&(2,0): share 2 -> (1,2) shifted
        assert alpha[0, 3] == 0  # same pair, two shared sensors
        # the wrong sign (t + tau) would put the clicks 2 tau away: no match
        wrong = click_match(tdoas[0].click_times_s + tdoas[0].tau_s, tdoas[1].click_times_s, SIG)
        assert wrong < 1e-6

    def test_orientation_invariant(self):
        """Reversing any TDOA (pair (j, i), -tau, clicks at j) leaves alpha and the closure unchanged."""
        emit = emissions(20, 12)
        tdoas = geometric_tdoas(np.array([1.2, 0.7, 1.9, 0.4]), emit, [(0, 1), (1, 2), (0, 2), (3, 1)])
        flipped = [t.reversed() if k % 2 else t for k, t in enumerate(tdoas)]
        assert_allclose(cross_pair_alpha(flipped), cross_pair_alpha(tdoas), rtol=1e-12)
        assert_allclose(closure_check(flipped).residual_s, closure_check(tdoas).residual_s, atol=1e-12)

    def test_two_sources_do_not_associate(self):
        """TDOAs of different whales on pairs sharing a sensor have alpha ~ 0."""
        d = np.array([1.2, 0.7, 1.9])
        a = geometric_tdoas(d, emissions(20, 9), [(0, 1)])
        b = geometric_tdoas(d + 0.1, emissions(20, 10), [(1, 2)])
        assert cross_pair_alpha(a + b)[0, 1] < 0.5

    @settings(max_examples=40, deadline=None)
    @given(st.data())
    def test_symmetric_zero_diagonal_and_sharing_rule(self, data):
        """alpha is symmetric, zero on the diagonal, and 0 unless exactly one sensor is shared."""
        m = data.draw(st.integers(1, 7))
        pairs = data.draw(st.lists(st.tuples(st.integers(0, 4), st.integers(0, 4))
                                   .filter(lambda p: p[0] != p[1]), min_size=m, max_size=m))
        base = np.sort(data.draw(st.lists(st.floats(0, 5), min_size=1, max_size=15)))
        taus = data.draw(st.lists(st.floats(-0.01, 0.01), min_size=m, max_size=m))
        tdoas = [TdoaClicks(p, t, base + 0.5 * t) for p, t in zip(pairs, taus, strict=True)]
        alpha = cross_pair_alpha(tdoas, sigma_t_s=2e-3)
        assert_allclose(alpha, alpha.T, rtol=1e-12, atol=0)
        assert np.all(np.diag(alpha) == 0)
        for i in range(m):
            for j in range(m):
                if len(set(pairs[i]) & set(pairs[j])) != 1:
                    assert alpha[i, j] == 0


class TestClosureCheck:
    def four_sensor_tdoas(self, *, sigma_s=None):
        emit = emissions(25, 11)
        delays = np.array([1.10, 0.62, 1.87, 1.45])
        pairs = [(0, 1), (2, 0), (0, 3), (1, 2), (3, 1), (2, 3)]  # mixed orientations
        return geometric_tdoas(delays, emit, pairs, sigma_s=sigma_s)

    def test_geometric_tdoas_close(self):
        """TDOAs of one source close every triangle: residual 0, all consistent."""
        check = closure_check(self.four_sensor_tdoas())
        assert_allclose(check.residual_s, 0.0, atol=1e-12)
        assert check.consistent.all()
        assert check.n_triples.tolist() == [2] * 6  # each pair lies on two of the four triangles
        assert_allclose(check.tolerance_s, 5e-4)

    def test_flags_corrupted_tdoa(self):
        """A TDOA 2 ms off (clicks unchanged) fails its triangles; the others still close."""
        tdoas = self.four_sensor_tdoas()
        bad = tdoas[3]
        tdoas[3] = TdoaClicks(bad.pair, bad.tau_s + 2e-3, bad.click_times_s)
        check = closure_check(tdoas)
        assert not check.consistent[3]
        assert_allclose(check.residual_s[3], 2e-3, atol=1e-12)
        assert check.consistent[[0, 1, 2, 4, 5]].all()

    def test_tolerance_from_sigmas(self):
        """With TDOA sigmas known, a triple's tolerance is 3 sqrt(sum of variances)."""
        tdoas = self.four_sensor_tdoas(sigma_s=1e-4)
        check = closure_check(tdoas)
        assert_allclose(check.tolerance_s, 3 * np.sqrt(3) * 1e-4, rtol=1e-12)
        bad = tdoas[0]
        tdoas[0] = TdoaClicks(bad.pair, bad.tau_s + 6e-4, bad.click_times_s, 1e-4)
        assert closure_check(tdoas).consistent.tolist() == [False] + [True] * 5
        assert closure_check(tdoas, tol_s=1e-3).consistent.all()

    def test_unassociated_triples_not_tested(self):
        """Triangles of TDOAs from different whales (alpha ~ 0) are not tested."""
        d = np.array([1.10, 0.62, 1.87])
        tdoas = [geometric_tdoas(d, emissions(20, s), [p])[0]
                 for s, p in zip((1, 2, 3), [(0, 1), (1, 2), (0, 2)], strict=True)]
        check = closure_check(tdoas)
        assert not check.tested.any() and not check.consistent.any()
        assert np.isnan(check.residual_s).all()

    def test_bad_alpha_shape(self):
        """An alpha of the wrong shape raises ValueError."""
        with pytest.raises(ValueError, match="alpha"):
            closure_check(self.four_sensor_tdoas(), np.zeros((2, 2)))


class TestTdoaClicks:
    def test_reversed_round_trip(self):
        """Reversing twice gives the original; times at j are t_i - tau."""
        t = TdoaClicks((3, 1), 0.25, [1.0, 2.0], 1e-4)
        assert_allclose(t.reversed().click_times_s, [0.75, 1.75])
        back = t.reversed().reversed()
        assert back.pair == (3, 1) and back.tau_s == 0.25 and back.sigma_s == 1e-4
        assert_allclose(back.click_times_s, t.click_times_s)

    @pytest.mark.parametrize(
        ("args", "match"),
        [(((1, 1), 0.1, [1.0]), "pair"), (((0, 1), np.nan, [1.0]), "tau_s"),
         (((0, 1), 0.1, [[1.0]]), "click_times_s"), (((0, 1), 0.1, [1.0], -1.0), "sigma_s")],
    )
    def test_bad_fields(self, args, match):
        """Bad fields raise ValueError naming them."""
        with pytest.raises(ValueError, match=match):
            TdoaClicks(*args)

    def test_times_at_other_sensor(self):
        """times_at refuses a sensor outside the pair."""
        with pytest.raises(ValueError, match="not in pair"):
            TdoaClicks((0, 1), 0.1, [1.0]).times_at(2)
