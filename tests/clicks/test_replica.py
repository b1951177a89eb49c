"""Tests of the click replica: shipped file, resampling, correlation (eq. 1), iterative estimate."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal
from numpy.testing import assert_allclose

from fusion.clicks.detect import ClickDetector
from fusion.clicks.replica import (
    GENERIC_FS,
    GENERIC_PATH,
    GENERIC_VERSION,
    Replica,
    correlate_replica,
    estimate_replica,
    fourier_shift,
    generic_replica,
    load_replica,
    peak_correlation,
    resample_replica,
    write_replica,
)
from fusion.simulate.clicks import ClickWaveform, simulate_clicks

FS = 96_000.0


def _zero_lag(a: np.ndarray, b: np.ndarray) -> float:
    """Normalised correlation of two odd-length waveforms with their centres aligned."""
    n = min(a.size, b.size)
    a = a[(a.size - n) // 2:(a.size + n) // 2]
    b = b[(b.size - n) // 2:(b.size + n) // 2]
    return float(a @ b / np.linalg.norm(a) / np.linalg.norm(b))


# --------------------------------------------------------------------------------------------
# shipped replica and resampling
# --------------------------------------------------------------------------------------------
def test_shipped_replica_is_the_generic_sweep():
    """The shipped npz holds plain arrays equal to generic_replica() at GENERIC_FS, unit energy."""
    with np.load(GENERIC_PATH, allow_pickle=False) as z:
        assert set(z.files) == {"replica", "fs", "version"}
        assert z["replica"].dtype == np.float64
        assert float(z["fs"]) == GENERIC_FS
        assert str(z["version"]) == GENERIC_VERSION
    rep = load_replica()
    assert_allclose(rep.samples, generic_replica(GENERIC_FS), atol=1e-15)
    assert rep.samples.size % 2 == 1
    assert_allclose(rep.samples @ rep.samples, 1.0, rtol=1e-12)


def test_generic_replica_is_an_upsweep_different_from_the_simulated_click():
    """The generic replica sweeps upwards in its band and matches the simulated click only
    partly (a generic, not a copy)."""
    r = generic_replica(FS)
    analytic = scipy.signal.hilbert(np.pad(r, 64))[64:-64]
    inst_f = np.diff(np.unwrap(np.angle(analytic))) * FS / (2 * np.pi)
    mid = slice(r.size // 4, 3 * r.size // 4)
    slope = np.polyfit(np.arange(inst_f.size)[mid] / FS, inst_f[mid], 1)[0]
    assert_allclose(slope, 20e3 / 270e-6, rtol=0.2)  # Hz/s of the 26-46 kHz, 270 us sweep
    assert 26e3 < inst_f[mid].mean() < 46e3
    rho = peak_correlation(r, ClickWaveform().replica(FS))
    assert 0.7 < rho < 0.95


def test_write_and_load_round_trip(tmp_path):
    """write_replica/load_replica keep samples, rate and version."""
    rep = Replica(generic_replica(FS), FS, "test-v0")
    back = load_replica(write_replica(tmp_path / "r.npz", rep))
    assert_allclose(back.samples, rep.samples, atol=1e-15)
    assert (back.fs, back.version) == (FS, "test-v0")


def test_load_replica_rejects_missing_keys_and_pickles(tmp_path):
    """A file without the three keys, or with an object array, is refused."""
    np.savez(tmp_path / "a.npz", replica=np.ones(5), fs=1.0)
    with pytest.raises(ValueError, match="lacks"):
        load_replica(tmp_path / "a.npz")
    np.savez(tmp_path / "b.npz", replica=np.array([object()]), fs=1.0, version="x")
    with pytest.raises(ValueError):
        load_replica(tmp_path / "b.npz")


def test_resampling_matches_direct_synthesis_and_keeps_the_centre():
    """192 kHz -> 96 kHz and 192 kHz -> 120 kHz equal the sweep synthesised at that rate, centre
    on the middle sample (zero-lag correlation, not only peak)."""
    for fs in (96_000.0, 120_000.0):
        got = load_replica().at(fs)
        assert got.size % 2 == 1
        assert _zero_lag(got, generic_replica(fs)) > 0.99
    r96 = generic_replica(FS)
    back = resample_replica(resample_replica(r96, FS, 2 * FS), 2 * FS, FS)
    assert _zero_lag(back, r96) > 0.99  # 44-48 kHz lies in the anti-alias filter's skirt


def test_fourier_shift_integer_and_fractional():
    """An integer shift moves samples with zero fill; a fractional one delays a band-limited
    tone by that many samples."""
    x = np.zeros(32)
    x[10] = 1.0
    assert_allclose(fourier_shift(x, 3.0), np.roll(x, 3), atol=1e-12)
    t = np.arange(400.0)

    def pulse(u):
        return np.cos(2 * np.pi * 0.05 * u) * np.exp(-0.5 * ((u - 200) / 40) ** 2)

    assert_allclose(fourier_shift(pulse(t), 0.4), pulse(t - 0.4), atol=1e-5)
    assert_allclose(fourier_shift(np.stack([pulse(t), pulse(t)]), [0.4, -1.7]),
                    np.stack([pulse(t - 0.4), pulse(t + 1.7)]), atol=1e-5)


# --------------------------------------------------------------------------------------------
# correlation (eq. 1)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n_rep", [5, 6, 27])
def test_correlation_equals_direct_numpy_correlate(n_rep):
    """correlate_replica equals np.correlate ('full', re-centred) for 1-D and 2-D input, odd and
    even replica lengths, in float64 exactly and in float32 to 1e-5 of the peak."""
    rng = np.random.default_rng(n_rep)
    x = rng.standard_normal((200, 3))
    r = rng.standard_normal(n_rep)
    h = (n_rep - 1) // 2
    ref = np.column_stack([np.correlate(x[:, c], r, "full")[n_rep - 1 - h:n_rep - 1 - h + 200]
                           for c in range(3)])
    assert_allclose(correlate_replica(x, r, dtype=np.float64), ref, atol=1e-12)
    assert_allclose(correlate_replica(x[:, 1], r, dtype=np.float64), ref[:, 1], atol=1e-12)
    y32 = correlate_replica(x, r)
    assert y32.dtype == np.float32
    assert_allclose(y32, ref, atol=1e-5 * np.abs(ref).max())


def test_a_click_centred_at_t_peaks_at_t():
    """Correlating a replica placed with its centre at sample t gives the maximum at t."""
    r = load_replica().at(FS)
    h = (r.size - 1) // 2
    for t in (40, 41, 77):
        x = np.zeros(150)
        x[t - h:t - h + r.size] = r
        assert int(np.argmax(correlate_replica(x, r))) == t


def test_correlation_rejects_bad_input():
    """NaN samples, 3-D input and an empty replica raise ValueError naming the problem."""
    with pytest.raises(ValueError, match="NaN"):
        correlate_replica(np.array([0.0, np.nan, 1.0]), [1.0])
    with pytest.raises(ValueError, match="shape"):
        correlate_replica(np.zeros((4, 2, 2)), [1.0])
    with pytest.raises(ValueError, match="replica"):
        correlate_replica(np.zeros(4), [])


# --------------------------------------------------------------------------------------------
# iterative estimate (step 32)
# --------------------------------------------------------------------------------------------
def test_estimate_recovers_the_true_click_from_noisy_detections():
    """From the generic replica and detector output on a 20 dB recording, the estimate converges
    to a waveform within 0.95 normalised correlation of the true click, closer than the generic."""
    sc = simulate_clicks(seed=3, n_sensors=5, n_sources=1, duration_s=15.0, snr_db=20.0,
                         n_transients=0)
    det = ClickDetector(threshold=20.0)  # strong clicks only, as the method trains on
    clicks = det.detect(sc.audio, sc.fs)
    assert sum(c.n_clicks for c in clicks) > 40
    est = estimate_replica(sc.audio, sc.fs, clicks, initial=load_replica(), n_iter=6)
    true = sc.click.replica(sc.fs)
    rho_est = peak_correlation(est.replica.samples, true)
    rho_gen = peak_correlation(load_replica().at(sc.fs), true)
    assert rho_est > 0.95
    assert rho_est > rho_gen + 0.05
    assert est.n_iterations == len(est.changes) <= 6
    assert est.changes[-1] < est.changes[0]
    assert est.replica.fs == sc.fs and est.replica.samples.size % 2 == 1
    assert_allclose(np.linalg.norm(est.replica.samples), 1.0, rtol=1e-12)


def test_estimate_is_a_fixed_point_at_the_true_click():
    """Noise-free clicks at random sub-sample times, starting from the true waveform: the
    estimate stays the true waveform, centred (zero-lag correlation > 0.999)."""
    rng = np.random.default_rng(0)
    cw = ClickWaveform()
    n = 20_000
    times = np.sort(rng.uniform(0.01, n / FS - 0.01, 30))
    times = times[np.concatenate([[True], np.diff(times) > 0.002])]
    x = sum(cw.evaluate(np.arange(n) / FS - t) for t in times)
    true = cw.replica(FS)
    est = estimate_replica(x, FS, times, initial=true, half_len_s=12 / FS, n_iter=3, tol=1e-6)
    r = est.replica.samples
    assert r.size == true.size
    assert r @ true / np.linalg.norm(true) > 0.999
    assert est.change < 0.05


def test_estimate_rejects_bad_input():
    """No clicks, NaN audio, a wrong number of per-channel time lists, and a bad n_iter raise."""
    x = np.zeros((1000, 2))
    with pytest.raises(ValueError, match="at least one"):
        estimate_replica(x, FS, [[], []])
    with pytest.raises(ValueError, match="per channel"):
        estimate_replica(x, FS, [[0.005]])
    with pytest.raises(ValueError, match="NaN"):
        estimate_replica(np.full(100, np.nan), FS, [0.0005])
    with pytest.raises(ValueError, match="n_iter"):
        estimate_replica(x[:, 0], FS, [0.005], n_iter=0)
    with pytest.raises(ValueError, match="inside the audio"):
        estimate_replica(x[:, 0], FS, [0.0])
