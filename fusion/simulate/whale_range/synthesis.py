"""Building blocks of the click-scenario simulator: click trains, source motion, hydrophone
layout, exact rendering of transients on sampled channels and band-limited noise.

Used by :func:`fusion.simulate.clicks.simulate_clicks`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.fft
from numpy.typing import NDArray

__all__ = ["draw_emission_times"]


def draw_emission_times(
    *,
    ici_mean_s: float,
    ici_jitter_s: float,
    t_start_s: float,
    t_end_s: float,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """A click train: emission times with gamma-distributed inter-click intervals.

    Parameters
    ----------
    ici_mean_s : float
        Mean inter-click interval, s (the method text quotes 0.37 s for Blainville's beaked
        whales, paragraph [0036]).
    ici_jitter_s : float
        Standard deviation of the interval, s (0: perfectly periodic).
    t_start_s, t_end_s : float
        The first click falls uniformly in ``[t_start_s, t_start_s + ici_mean_s)``; the train
        stops before `t_end_s`.
    rng : numpy.random.Generator
        Random source.

    Returns
    -------
    ndarray, shape (n,)
        Increasing emission times, s.

    Notes
    -----
    A gamma distribution with shape ``(mean / std)^2`` and scale ``std^2 / mean`` has exactly the
    requested mean and standard deviation and never produces a non-positive interval (a clipped
    normal would bias both).
    """
    if not (np.isfinite(ici_mean_s) and ici_mean_s > 0):
        raise ValueError(f"ici_mean_s must be positive, got {ici_mean_s!r}")
    if not (np.isfinite(ici_jitter_s) and ici_jitter_s >= 0):
        raise ValueError(f"ici_jitter_s must be >= 0, got {ici_jitter_s!r}")
    if not (np.isfinite(t_start_s) and np.isfinite(t_end_s) and t_end_s > t_start_s):
        raise ValueError(f"need t_start_s < t_end_s, got {t_start_s!r}, {t_end_s!r}")
    first = t_start_s + ici_mean_s * rng.uniform()
    span = t_end_s - first
    times = [np.array([first])]
    last, n_block = first, int(np.ceil(max(span, 0.0) / ici_mean_s * 1.2)) + 8
    while last < t_end_s:
        if ici_jitter_s == 0:
            ici = np.full(n_block, ici_mean_s)
        else:
            ici = rng.gamma((ici_mean_s / ici_jitter_s) ** 2, ici_jitter_s**2 / ici_mean_s, n_block)
        block = last + np.cumsum(ici)
        times.append(block)
        last = float(block[-1])
    out = np.concatenate(times)
    return out[out < t_end_s]


def _positions(
    t: NDArray[np.float64],
    p0: NDArray[np.float64],
    speed: float,
    heading: float,
    turn_rate: float,
    vz: float,
) -> NDArray[np.float64]:
    """Constant-speed, constant-turn-rate motion in closed form; shape (m, 3)."""
    if abs(turn_rate) < 1e-12:
        dx, dy = speed * t * np.cos(heading), speed * t * np.sin(heading)
    else:
        h = heading + turn_rate * t
        # integral of v (cos h, sin h) dt with dh/dt = turn_rate
        dx = speed / turn_rate * (np.sin(h) - np.sin(heading))
        dy = -speed / turn_rate * (np.cos(h) - np.cos(heading))
    return np.column_stack([p0[0] + dx, p0[1] + dy, p0[2] + vz * t])


def _layout(n_sensors: int, rng: np.random.Generator, *, radius_m: float) -> NDArray[np.float64]:
    """Bottom-mounted hydrophones: a jittered ring (plus one near the centre for n >= 5)."""
    n_centre = 1 if n_sensors >= 5 else 0
    n_ring = n_sensors - n_centre
    ang = 2.0 * np.pi * (np.arange(n_ring) + rng.uniform(-0.15, 0.15, n_ring)) / n_ring
    ang += rng.uniform(0.0, 2.0 * np.pi)
    rad = radius_m * rng.uniform(0.85, 1.15, n_ring)
    xy = np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])
    if n_centre:
        xy = np.vstack([rng.uniform(-0.1, 0.1, 2) * radius_m, xy])
    z = -rng.uniform(1500.0, 1700.0, n_sensors)
    return np.column_stack([xy, z])


def _render(
    audio: NDArray[np.float32],
    times: NDArray[np.float64],
    channels: NDArray[np.int64],
    amplitudes: NDArray[np.float64],
    shape: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    before_s: float,
    after_s: float,
    fs: float,
) -> None:
    """Add ``amplitude * shape(t - time)`` on each channel, sampled exactly (in place)."""
    if times.size == 0:
        return
    n_len = int(np.ceil((before_s + after_s) * fs)) + 2
    start = np.floor((times - before_s) * fs).astype(np.int64)
    idx = start[:, None] + np.arange(n_len)[None, :]  # (n_events, n_len) sample indices
    vals = amplitudes[:, None] * shape(idx / fs - times[:, None])
    ch = np.broadcast_to(channels[:, None], idx.shape)
    keep = (idx >= 0) & (idx < audio.shape[0]) & (vals != 0.0)
    np.add.at(audio, (idx[keep], ch[keep]), vals[keep].astype(audio.dtype))


def _add_band_noise(
    audio: NDArray[np.float32],
    fs: float,
    band_hz: tuple[float, float],
    std: float,
    rng: np.random.Generator,
) -> None:
    """Add Gaussian noise with a flat spectrum inside `band_hz` and none outside, total std
    `std`, to every channel of `audio` (in place, one channel at a time to bound memory).

    The spectrum of white Gaussian noise has independent complex Gaussian bins, so the in-band
    bins are drawn directly and inverse transformed (no forward FFT of a white sequence).
    """
    n_samples = audio.shape[0]
    n_fft = scipy.fft.next_fast_len(n_samples, real=True)
    f = np.fft.rfftfreq(n_fft, 1.0 / fs)
    band = np.flatnonzero((f >= band_hz[0]) & (f <= band_hz[1]))
    spec = np.zeros(f.size, dtype=np.complex64)  # single precision: half the memory
    for ch in range(audio.shape[1]):
        spec.real[band] = rng.standard_normal(band.size, dtype=np.float32)
        spec.imag[band] = rng.standard_normal(band.size, dtype=np.float32)
        x = scipy.fft.irfft(spec, n_fft)[:n_samples]
        audio[:, ch] += x * np.float32(std / x.std(dtype=np.float64))


def _transient_shape(
    freqs: NDArray[np.float64], decay: NDArray[np.float64]
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """Damped sinusoid starting at tau = 0, per event (freqs/decay shape (n, 1))."""

    def shape(tau: NDArray[np.float64]) -> NDArray[np.float64]:
        on = (tau >= 0) & (tau <= 8.0 * decay)
        env = np.exp(-np.clip(tau, 0, None) / decay)
        # peak of exp(-t/d) sin(2 pi f t) is near 1 for short decays; normalise exactly
        return np.where(on, env * np.sin(2.0 * np.pi * freqs * tau), 0.0) / _peak(freqs, decay)

    return shape


def _peak(freqs: NDArray[np.float64], decay: NDArray[np.float64]) -> NDArray[np.float64]:
    """Peak of ``exp(-t/d) sin(2 pi f t)``: at ``t* = atan(2 pi f d) / (2 pi f)``."""
    w = 2.0 * np.pi * freqs
    t_star = np.arctan(w * decay) / w
    return np.exp(-t_star / decay) * np.sin(w * t_star)
