"""Sub-sample TDOA refinement, its Cramér-Rao bound and the delay-track fit."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fusion.clicks.delaytrack import (
    consensus_inliers,
    fit_delays,
    match_along_track,
    shift_matrix,
)
from fusion.clicks.tdoa import TdoaRefiner, rms_frequency_hz, tdoa_crb_s
from fusion.simulate.clicks import ClickWaveform

FS = 96_000.0
CLICK = ClickWaveform()


def two_channels(times_i, times_j, *, noise: float, rng, duration_s: float = 0.5,
                 amp_j: float = 1.0) -> np.ndarray:
    """Clicks at exact (fractional) times on two channels plus white noise of std `noise`."""
    n = int(duration_s * FS)
    audio = noise * rng.standard_normal((n, 2))
    h = int(np.ceil(CLICK.duration_s * FS))
    for ch, (times, amp) in enumerate(((times_i, 1.0), (times_j, amp_j))):
        for t in times:
            k = np.arange(int(t * FS) - h, int(t * FS) + h + 2)
            audio[k, ch] += amp * CLICK.evaluate(k / FS - t)
    return audio


def band_energy(fs: float = FS, band=(20_000.0, 46_000.0)) -> float:
    """Energy sum s[t]^2 of the click after an ideal band-pass (the ENR numerator)."""
    x = CLICK.replica(fs * 1.0)
    spec = np.fft.rfft(x, 4096)
    f = np.fft.rfftfreq(4096, 1.0 / fs)
    inb = (f >= band[0]) & (f <= band[1])
    return float(2.0 * np.sum(np.abs(spec[inb]) ** 2) / 4096)


@pytest.mark.parametrize("delay_samples", [0.0, 0.37, -1.5, 2.913, -7.25])
def test_high_snr_delay_within_005_sample(delay_samples):
    """Noise 60 dB below the click: refined tau = t_i - t_j to well within 0.05 sample."""
    rng = np.random.default_rng(1)
    ti = np.array([0.05, 0.17, 0.29, 0.41]) + 1.234e-6
    d = delay_samples / FS
    audio = two_channels(ti, ti - d, noise=1e-3, rng=rng)
    res = TdoaRefiner(fs_hz=FS).refine(audio, (0, 1), ti, ti - d)
    assert res is not None and res.n_clicks_used == 4
    # the sampled click is not strictly band-limited at 96 kHz: its aliasing near 48 kHz
    # leaves a deterministic ~0.002-sample error, far below the 0.05-sample requirement
    assert abs(res.tau_s - d) * FS < 0.05
    assert res.cycle_resolved


def test_sign_convention_and_pair_order():
    """Channel j hears the click 0.3 ms before channel i: pair (i, j) gives +0.3 ms, (j, i) -0.3 ms."""
    rng = np.random.default_rng(2)
    ti = np.array([0.1, 0.2, 0.3])
    tj = ti - 3e-4
    audio = two_channels(ti, tj, noise=1e-3, rng=rng)
    ref = TdoaRefiner(fs_hz=FS)
    assert_allclose(ref.refine(audio, (0, 1), ti, tj).tau_s, 3e-4, atol=1e-7)
    swapped = audio[:, ::-1]
    assert_allclose(ref.refine(swapped, (1, 0), ti, tj).tau_s, 3e-4, atol=1e-7)
    assert_allclose(ref.refine(swapped, (0, 1), tj, ti).tau_s, -3e-4, atol=1e-7)


def test_rms_error_near_crb_and_sigma_honest():
    """200 seeded trials at ~26 dB: RMS error within 1.5x the CRB, reported sigma within 1.5x RMS."""
    rng = np.random.default_rng(5)
    ref = TdoaRefiner(fs_hz=FS, max_degree=0)
    err, crb, sig = [], [], []
    for _ in range(200):
        ti = 0.05 + np.arange(4) * 0.1 + rng.uniform(0, 0.01, 4)
        d = rng.uniform(-3, 3) / FS
        audio = two_channels(ti, ti - d, noise=0.1, rng=rng, duration_s=0.5)
        jit = rng.normal(0, 2e-5, (2, 4))  # detection time errors
        r = ref.refine(audio, (0, 1), ti + jit[0], ti - d + jit[1])
        err.append(r.tau_s - d)
        crb.append(r.crb_s)
        sig.append(r.sigma_s)
    rms = np.sqrt(np.mean(np.square(err)))
    crb_rms = np.sqrt(np.mean(np.square(crb)))
    sig_rms = np.sqrt(np.mean(np.square(sig)))
    assert 0.8 * crb_rms < rms < 1.5 * crb_rms
    assert rms / 1.5 < sig_rms < 1.5 * rms


def test_measured_snr_matches_the_true_energy_to_noise_ratio():
    """snr_db equals 10 log10(E / sigma^2) of the band-limited click within 0.5 dB."""
    rng = np.random.default_rng(3)
    ti = 0.05 + np.arange(8) * 0.11
    noise = 0.05
    audio = two_channels(ti, ti - 1e-4, noise=noise, rng=rng, duration_s=1.0)
    res = TdoaRefiner(fs_hz=FS).refine(audio, (0, 1), ti, ti - 1e-4)
    true_db = 10 * np.log10(band_energy() / noise**2)
    assert abs(res.snr_db - true_db) < 0.5


def test_crb_equals_numerical_fisher_information():
    """tdoa_crb_s from the RMS frequency equals the bound from the numerical Fisher information."""
    fs = 2 * FS  # at 96 kHz the click's aliasing near 48 kHz makes the two differ by 1 %
    t0, sigma = 0.3e-3, 0.05
    t = np.arange(int(1e-3 * fs)) / fs
    eps = 1e-9
    ds = (CLICK.evaluate(t - t0 - eps) - CLICK.evaluate(t - t0 + eps)) / (2 * eps)  # d s / d t0
    var_one = sigma**2 / np.sum(ds**2)  # arrival-time bound of one channel: 1 / Fisher info
    x = CLICK.evaluate(t - t0)
    spec = np.fft.rfft(x, 1 << 14)
    beta = rms_frequency_hz(np.abs(spec) ** 2, np.fft.rfftfreq(1 << 14, 1.0 / fs))
    enr = np.sum(x**2) / sigma**2
    assert_allclose(tdoa_crb_s(beta, enr, enr), np.sqrt(2 * var_one), rtol=1e-4)
    # unequal SNRs: the two per-channel bounds add
    assert_allclose(tdoa_crb_s(beta, enr, enr / 4), np.sqrt(var_one * (1 + 4)), rtol=1e-4)


def test_drifting_curved_track_is_followed():
    """Clicks over 10 s with a drifting, curved TDOA: the fit follows it within its sigma."""
    rng = np.random.default_rng(8)
    ti = np.sort(0.2 + np.cumsum(rng.uniform(0.3, 0.45, 26)))
    ti = ti[ti < 10.0]

    def tau(t):
        return 2.0e-4 + 8e-4 * (t - 5.0) + 2e-6 * (t - 5.0) ** 2  # 12.5 us of curvature at the ends

    tj = ti - tau(ti)
    audio = two_channels(ti, tj, noise=0.02, rng=rng, duration_s=10.5)
    res = TdoaRefiner(fs_hz=FS).refine(audio, (0, 1), ti, tj, reference_time_s=5.0)
    assert res.degree == 2 and res.n_clicks_used == ti.size
    assert abs(res.tau_s - tau(5.0)) < 4 * res.sigma_s
    assert_allclose(res.rate, 8e-4, rtol=1e-3)
    grid = np.array([1.0, 3.0, 7.0, 9.5])
    est, sig = res.tau_at(grid)
    assert np.all(np.abs(est - tau(grid)) < 4 * sig)
    assert res.t_ref_s == 5.0 and res.birge < 2.0


def test_cycle_slip_resolved_at_moderate_snr():
    """At ~17 dB some clicks' peaks slip a carrier period; the track puts them back."""
    rng = np.random.default_rng(4)
    ti = 0.05 + np.arange(24) * 0.04
    d = 1.3 / FS
    audio = two_channels(ti, ti - d, noise=0.3, rng=rng, duration_s=1.1)
    res = TdoaRefiner(fs_hz=FS, max_degree=0).refine(audio, (0, 1), ti, ti - d)
    assert res.cycle_resolved and res.n_clicks_used >= 20
    assert np.all(np.abs(res.click_delays_s - d) < 0.5 * res.period_s)  # no slipped click left
    assert abs(res.tau_s - d) < 4 * res.sigma_s


def test_pure_noise_gives_none():
    """No click energy at the given times: nothing passes the SNR screen."""
    rng = np.random.default_rng(6)
    audio = rng.standard_normal((48_000, 2))
    assert TdoaRefiner(fs_hz=FS).refine(audio, (0, 1), [0.1, 0.2], [0.1, 0.2]) is None


def test_consensus_drops_slips_and_mismatches():
    """Delays on a drifting line with +-1 period slips and a 1 ms mismatch: exactly those go."""
    rng = np.random.default_rng(9)
    t = np.linspace(0.0, 11.0, 30)
    sig = np.full(30, 1e-6)
    d = 0.4 + 1e-3 * t + sig * rng.standard_normal(30)
    bad = np.array([3, 11, 12, 25])
    d[bad] += np.array([28e-6, -28e-6, 28e-6, 1e-3])
    keep = consensus_inliers(t, d, sig)
    assert_allclose(np.flatnonzero(~keep), bad)


def test_fit_delays_selects_the_degree_the_data_support():
    """Constant, linear and curved delay tracks give degrees 0, 1 and 2; coefficients recovered."""
    rng = np.random.default_rng(10)
    t = np.linspace(0.0, 10.0, 25)
    sig = np.full(25, 1e-6)
    noise = sig * rng.standard_normal(25)
    for coefs, deg in (([1e-3], 0), ([1e-3, 5e-4], 1), ([1e-3, 5e-4, 3e-6], 2)):
        true = np.polynomial.polynomial.polyval(t - 5.0, coefs)
        c, cov, t_ref, birge = fit_delays(t, true + noise, sig, max_degree=2)
        assert c.size == deg + 1
        assert_allclose(t_ref, 5.0)
        assert np.all(np.abs(c - coefs) < 5 * np.sqrt(np.diag(cov)))
        assert 0.5 < birge < 1.6


def test_shift_matrix_reexpands_a_polynomial():
    """sum c_k u^k equals sum (S c)_k (u - dt)^k."""
    c = np.array([0.3, -1.2, 0.7, 0.05])
    u = np.linspace(-3, 3, 7)
    s = shift_matrix(4, 1.7)
    assert_allclose(np.polynomial.polynomial.polyval(u, c),
                    np.polynomial.polynomial.polyval(u - 1.7, s @ c), atol=1e-12)


def test_match_along_track_follows_the_drift():
    """Seeded with 3 SCM2 matches mid-window, every click pair of the drifting train is matched."""
    rng = np.random.default_rng(12)
    ta = np.sort(0.1 + np.cumsum(rng.uniform(0.3, 0.45, 32)))
    ta = ta[ta < 12.0]
    tau = 0.3 + 1.5e-3 * (ta - 6.0) + 1e-6 * (ta - 6.0) ** 2  # 18 ms of drift through the window
    tj_a = ta - tau + rng.normal(0, 2e-5, ta.size)
    ti = np.sort(np.r_[ta + rng.normal(0, 2e-5, ta.size), rng.uniform(0, 12, 25)])  # + whale B
    tj = np.sort(np.r_[tj_a, rng.uniform(-0.5, 12, 25)])
    ia = np.searchsorted(ti, ta - 1e-4)  # positions of whale A's clicks in ti
    ja = np.searchsorted(tj, tj_a - 1e-9)
    mid = np.flatnonzero(np.abs(ta - 6.0) < 0.6)[:3]
    ii, jj = match_along_track(ti, tj, ia[mid], ja[mid], t_start_s=0.0, t_end_s=12.0)
    found = dict(zip(ii.tolist(), jj.tolist(), strict=True))
    assert all(found.get(int(a)) == int(b) for a, b in zip(ia, ja, strict=True))
    assert len(found) <= ia.size + 1  # at most a chance coincidence of whale B


def test_bad_inputs_raise():
    """Invalid options and inputs raise ValueError naming the problem."""
    with pytest.raises(ValueError, match="band_hz"):
        TdoaRefiner(fs_hz=FS, band_hz=(20e3, 60e3))
    with pytest.raises(ValueError, match="max_lag_s"):
        TdoaRefiner(fs_hz=FS, max_lag_s=1e-3, half_window_s=4e-4)
    with pytest.raises(ValueError, match="max_degree"):
        TdoaRefiner(fs_hz=FS, max_degree=5)
    ref = TdoaRefiner(fs_hz=FS)
    with pytest.raises(ValueError, match="audio"):
        ref.refine(np.zeros(100), (0, 1), [0.0], [0.0])
    with pytest.raises(ValueError, match="pair"):
        ref.refine(np.zeros((100, 2)), (0, 0), [0.0], [0.0])
    with pytest.raises(ValueError, match="one length"):
        ref.refine(np.zeros((100, 2)), (0, 1), [0.0, 0.1], [0.0])
    with pytest.raises(ValueError, match="ratios"):
        tdoa_crb_s(3e4, 0.0, 1.0)
    with pytest.raises(ValueError, match="power"):
        rms_frequency_hz([-1.0, 1.0], [1.0, 2.0])


def _same(a, b) -> bool:
    """Two refined TDOAs equal to the bit (None equals None)."""
    if a is None or b is None:
        return a is b
    return all(np.array_equal(np.asarray(getattr(a, f)), np.asarray(getattr(b, f)))
               for f in ("tau_s", "sigma_s", "crb_s", "rate", "snr_db", "click_times_s",
                         "click_delays_s", "coef"))


def test_remembered_cuts_give_the_same_bits_across_overlapping_windows():
    """A refiner that remembers click cuts (one per stream of windows) measures every pair of
    overlapping windows exactly as a fresh refiner does, computes each cut's spectrum once,
    and forgets the cuts before a sample when told."""
    rng = np.random.default_rng(11)
    ti = np.sort(rng.uniform(0.02, 1.45, 14))
    audio = two_channels(ti, ti - 1.7e-4, noise=0.05, rng=rng, duration_s=1.5)
    memo = TdoaRefiner(fs_hz=FS).remember_cuts()
    assert memo._memo is not None and TdoaRefiner(fs_hz=FS)._memo is None
    n_spectra = []
    for a0, b0 in ((0, 96_000), (24_000, 120_000), (48_000, 144_000)):  # 1-s windows, 0.25 s hop
        x, t0 = audio[a0:b0], a0 / FS
        sel = (ti > t0 + 0.01) & (ti < b0 / FS - 0.01)
        args = (x, (0, 1), ti[sel], ti[sel] - 1.7e-4)
        fresh = TdoaRefiner(fs_hz=FS).refine(*args, audio_t0_s=t0, reference_time_s=t0 + 0.5)
        kept = memo.refine(*args, audio_t0_s=t0, reference_time_s=t0 + 0.5)
        assert fresh is not None and _same(fresh, kept)
        n_spectra.append(len(memo._memo.spectra))
    # the second and third windows add only the clicks they do not share with the first
    assert n_spectra[-1] == 2 * np.sum((ti > 0.01) & (ti < 1.49))
    memo.forget_before(48_000)
    starts = [k[1] for k in memo._memo.spectra] + [min(k[2:]) for k in memo._memo.correlations]
    assert starts and min(starts) >= 48_000
