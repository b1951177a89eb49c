"""Beaked-whale-like click trains received on widely spaced bottom-mounted hydrophones.

The scenario is the one the click pipeline (``fusion localize``) is built for — the setting of
*Localization of Short Duration Periodic Signals* (Baggenstoss, NUWC 102089, paragraphs
[0028]–[0036]): hydrophones kilometres apart on the sea floor sampled at 96 kHz, Blainville's
beaked whales emitting short FM upswept clicks at an inter-click interval (ICI) near 0.37 s.

Physics (every choice explicit, see :func:`simulate_clicks`):

* straight-line propagation at the array's constant sound speed; each click leaves the source
  at its emission time from the source's position at that time;
* spherical spreading (``1/r`` amplitude) and a frequency-flat absorption loss in dB/km;
* one surface-reflected path per click and sensor, from the image source ``(x, y, -z)`` with a
  reflection coefficient (default -0.9, a phase-inverting pressure-release surface);
* white ambient noise, band-limited to ``noise_band_hz``, at a stated in-band SNR;
* optional impulsive false transients (damped sinusoids) on single channels.

Each click is synthesised analytically at its exact (continuous) arrival time, so the sampled
audio carries arrival times exact to well under a sample.

Examples
--------
>>> sc = simulate_clicks(seed=1, n_sensors=3, n_sources=1, duration_s=2.0)
>>> sc.audio.shape
(192000, 3)
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.fft
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import SensorArray
from fusion.io import (
    write_array,
    write_audio,
    write_json,
    write_table,
)

__all__ = [
    "ClickScenario",
    "ClickWaveform",
    "WhaleTrack",
    "draw_emission_times",
    "simulate_clicks",
    "truth_document",
    "write_click_scenario",
    "write_scenario",
]

logger = logging.getLogger(__name__)

#: Peak level the written FLAC file is scaled to (headroom below the 24-bit full scale of 1).
FILE_PEAK = 0.5


def _frozen(a: ArrayLike, dtype: Any = float) -> NDArray[Any]:
    out = np.array(a, dtype=dtype)
    out.setflags(write=False)
    return out


# --------------------------------------------------------------------------------------------
# data
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ClickWaveform:
    """A Hann-tapered linear FM upsweep, the model of one beaked-whale click.

    Attributes
    ----------
    f_start_hz : float
        Instantaneous frequency at the start of the click, Hz.
    f_end_hz : float
        Instantaneous frequency at the end of the click, Hz (above `f_start_hz`: an upsweep).
    duration_s : float
        Total length of the click, s.

    Notes
    -----
    With ``D`` the duration, ``f_m = (f_start + f_end) / 2`` and ``k = (f_end - f_start) / D``,
    the click centred at ``tau = 0`` is::

        s(tau) = cos^2(pi tau / D) * cos(2 pi (f_m tau + k tau^2 / 2)),   |tau| <= D / 2

    and 0 elsewhere: unit peak at the centre, instantaneous frequency ``f_m + k tau`` sweeping
    from `f_start_hz` to `f_end_hz`. Arrival and emission times in this module are times of the
    click centre.
    """

    f_start_hz: float = 25_000.0
    f_end_hz: float = 45_000.0
    duration_s: float = 250e-6

    def __post_init__(self) -> None:
        vals = (self.f_start_hz, self.f_end_hz, self.duration_s)
        if not all(np.isfinite(v) and v > 0 for v in vals):
            raise ValueError(f"click frequencies and duration must be positive, got {vals}")
        if self.f_end_hz <= self.f_start_hz:
            raise ValueError(
                f"click must sweep upwards: f_end_hz={self.f_end_hz} <= f_start_hz={self.f_start_hz}"
            )

    @property
    def band_hz(self) -> tuple[float, float]:
        """``(f_start_hz, f_end_hz)``, the click band."""
        return (float(self.f_start_hz), float(self.f_end_hz))

    def evaluate(self, tau: ArrayLike) -> NDArray[np.float64]:
        """The click at times `tau` relative to its centre.

        Parameters
        ----------
        tau : array_like, any shape
            Time from the click centre, s.

        Returns
        -------
        ndarray, same shape as `tau`
            Waveform (unit peak amplitude), 0 outside ``|tau| <= duration_s / 2``.
        """
        t = np.asarray(tau, dtype=float)
        d = self.duration_s
        f_mid = 0.5 * (self.f_start_hz + self.f_end_hz)
        sweep = (self.f_end_hz - self.f_start_hz) / d
        env = np.where(np.abs(t) <= 0.5 * d, np.cos(np.pi * t / d) ** 2, 0.0)
        return env * np.cos(2.0 * np.pi * (f_mid * t + 0.5 * sweep * t * t))

    def replica(self, fs: float) -> NDArray[np.float64]:
        """The click sampled at `fs`, centred on the middle sample (a matched-filter replica).

        Parameters
        ----------
        fs : float
            Sample rate, Hz.

        Returns
        -------
        ndarray, shape (2 h + 1,)
            ``s(k / fs)`` for ``k = -h .. h``, ``h = ceil(duration_s * fs / 2)``.
        """
        if not np.isfinite(fs) or fs <= 0:
            raise ValueError(f"fs must be positive, got {fs!r}")
        h = int(np.ceil(0.5 * self.duration_s * fs))
        return self.evaluate(np.arange(-h, h + 1) / fs)


@dataclass(frozen=True)
class WhaleTrack:
    """One simulated source: its motion, its click train and what each sensor receives.

    Attributes
    ----------
    source_id : int
        Index of the source in the scenario.
    start_position : ndarray, shape (3,)
        Position at ``t = 0``, m (z negative below the surface).
    speed_mps : float
        Horizontal speed, m/s.
    heading_rad : float
        Horizontal direction of motion at ``t = 0``, rad, counter-clockwise from east (+x).
    turn_rate_rad_s : float
        Constant rate of change of the heading, rad/s (a circular arc; 0 = straight line).
    vertical_rate_mps : float
        Rate of change of z, m/s.
    ici_mean_s : float
        Mean inter-click interval, s.
    ici_jitter_s : float
        Standard deviation of the inter-click interval, s.
    emission_times : ndarray, shape (n_clicks,)
        Times the click centres leave the source, s from the start of the audio (may be negative
        for clicks emitted before the recording whose arrivals fall inside it).
    positions : ndarray, shape (n_clicks, 3)
        Source position at each emission, m.
    source_amplitudes : ndarray, shape (n_clicks,)
        Peak amplitude of each click at the reference range along the direct path (1 for the
        nominal source level; per-click level jitter makes it vary).
    arrival_times : ndarray, shape (n_clicks, n_sensors)
        Direct-path arrival time of each click centre at each sensor, s.
    arrival_amplitudes : ndarray, shape (n_clicks, n_sensors)
        Peak amplitude of each direct-path arrival, in scenario units (noise is
        ``ClickScenario.noise_std_band`` in the click band).
    echo_arrival_times : ndarray, shape (n_clicks, n_sensors)
        Arrival time of the surface-reflected path (image source at ``(x, y, -z)``), s.
    echo_amplitudes : ndarray, shape (n_clicks, n_sensors)
        Signed peak amplitude of each surface echo (negative: phase inverted).
    """

    source_id: int
    start_position: NDArray[np.float64]
    speed_mps: float
    heading_rad: float
    turn_rate_rad_s: float
    vertical_rate_mps: float
    ici_mean_s: float
    ici_jitter_s: float
    emission_times: NDArray[np.float64]
    positions: NDArray[np.float64]
    source_amplitudes: NDArray[np.float64]
    arrival_times: NDArray[np.float64]
    arrival_amplitudes: NDArray[np.float64]
    echo_arrival_times: NDArray[np.float64]
    echo_amplitudes: NDArray[np.float64]

    def __post_init__(self) -> None:
        for name in (
            "start_position", "emission_times", "positions", "source_amplitudes",
            "arrival_times", "arrival_amplitudes", "echo_arrival_times", "echo_amplitudes",
        ):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        n = self.emission_times.shape[0]
        if self.positions.shape != (n, 3) or self.arrival_times.shape[0] != n:
            raise ValueError("WhaleTrack arrays disagree on the number of clicks")

    @property
    def n_clicks(self) -> int:
        """Number of emitted clicks."""
        return int(self.emission_times.shape[0])

    def position_at(self, times: ArrayLike) -> NDArray[np.float64]:
        """Source position at arbitrary times (the motion model, evaluated in closed form).

        Parameters
        ----------
        times : array_like, shape (m,)
            Times, s from the start of the audio.

        Returns
        -------
        ndarray, shape (m, 3)
            Positions, m.
        """
        return _positions(
            np.atleast_1d(np.asarray(times, dtype=float)), self.start_position,
            self.speed_mps, self.heading_rad, self.turn_rate_rad_s, self.vertical_rate_mps,
        )

    def tdoas(self, pairs: ArrayLike) -> NDArray[np.float64]:
        """Direct-path time differences of arrival of every click.

        Parameters
        ----------
        pairs : array_like of int, shape (k, 2)
            Sensor index pairs ``(i, j)``.

        Returns
        -------
        ndarray, shape (n_clicks, k)
            ``t_i - t_j``, s.
        """
        pr = np.asarray(pairs, dtype=int).reshape(-1, 2)
        return self.arrival_times[:, pr[:, 0]] - self.arrival_times[:, pr[:, 1]]


@dataclass(frozen=True)
class ClickScenario:
    """A simulated multichannel click recording and its ground truth.

    Attributes
    ----------
    seed : int
        Seed the scenario was drawn with.
    sensors : SensorArray
        The hydrophones; audio channel i is ``sensors.positions[i]``.
    fs : float
        Sample rate, Hz.
    duration_s : float
        Length of the audio, s.
    sources : tuple of WhaleTrack
        The clicking sources.
    audio : ndarray, shape (n_samples, n_sensors), float32
        Received pressure in scenario units: a click at the reference range has unit peak.
    click : ClickWaveform
        The emitted click.
    snr_db : float
        ``20 log10(1 / noise_std_band)``: peak direct-path click amplitude at the reference
        range over the noise standard deviation in the click band (``inf``: no noise).
    reference_range_m : float
        Range at which a nominal click has unit peak amplitude, m.
    noise_std_band : float
        Standard deviation of the ambient noise within the click band (scenario units).
    noise_std : float
        Standard deviation of the whole band-limited ambient noise (scenario units).
    noise_band_hz : tuple of float
        Band of the (flat-spectrum) ambient noise, Hz.
    absorption_db_per_km : float
        Absorption loss, dB/km (frequency flat).
    surface_reflection : float
        Reflection coefficient of the sea surface (0: no echo).
    transient_times : ndarray, shape (n_transients,)
        Onset times of the false transients, s.
    transient_channels : ndarray of int, shape (n_transients,)
        Channel of each transient.
    transient_amplitudes : ndarray, shape (n_transients,)
        Peak amplitude of each transient (scenario units).
    transient_freqs_hz : ndarray, shape (n_transients,)
        Ringing frequency of each transient, Hz.
    """

    seed: int
    sensors: SensorArray
    fs: float
    duration_s: float
    sources: tuple[WhaleTrack, ...]
    audio: NDArray[np.float32]
    click: ClickWaveform
    snr_db: float
    reference_range_m: float
    noise_std_band: float
    noise_std: float
    noise_band_hz: tuple[float, float]
    absorption_db_per_km: float
    surface_reflection: float
    transient_times: NDArray[np.float64] = field(default_factory=lambda: _frozen([]))
    transient_channels: NDArray[np.int64] = field(default_factory=lambda: _frozen([], int))
    transient_amplitudes: NDArray[np.float64] = field(default_factory=lambda: _frozen([]))
    transient_freqs_hz: NDArray[np.float64] = field(default_factory=lambda: _frozen([]))

    def __post_init__(self) -> None:
        audio = np.asarray(self.audio)
        if audio.ndim != 2 or audio.shape[1] != self.sensors.n_sensors:
            raise ValueError(
                f"audio shape {audio.shape} does not match {self.sensors.n_sensors} sensors"
            )
        audio.setflags(write=False)
        object.__setattr__(self, "audio", audio)
        object.__setattr__(self, "sources", tuple(self.sources))
        for name in ("transient_times", "transient_amplitudes", "transient_freqs_hz"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))
        object.__setattr__(self, "transient_channels", _frozen(self.transient_channels, int))

    @property
    def n_sensors(self) -> int:
        """Number of hydrophones (audio channels)."""
        return self.sensors.n_sensors

    @property
    def n_samples(self) -> int:
        """Number of audio samples per channel."""
        return int(self.audio.shape[0])

    @property
    def n_clicks(self) -> int:
        """Number of emitted clicks, all sources."""
        return sum(s.n_clicks for s in self.sources)

    def pairs(self) -> list[tuple[int, int]]:
        """All sensor pairs ``(i, j)``, ``i < j``."""
        return self.sensors.pairs()


# --------------------------------------------------------------------------------------------
# building blocks
# --------------------------------------------------------------------------------------------
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


# --------------------------------------------------------------------------------------------
# the simulator
# --------------------------------------------------------------------------------------------
def simulate_clicks(
    *,
    seed: int,
    n_sensors: int = 5,
    n_sources: int = 2,
    duration_s: float = 30.0,
    fs: float = 96_000.0,
    snr_db: float = 30.0,
    n_transients: int = 8,
    sound_speed: float = 1500.0,
    array_radius_m: float = 1500.0,
    reference_range_m: float = 1000.0,
    absorption_db_per_km: float = 8.0,
    surface_reflection: float = -0.9,
    noise_band_hz: tuple[float, float] = (1_000.0, 46_000.0),
    click: ClickWaveform | None = None,
    ici_s: float = 0.37,
    ici_jitter_s: float = 0.03,
    level_jitter_db: float = 2.0,
    speed_range_mps: tuple[float, float] = (1.0, 2.0),
    max_turn_rate_deg_s: float = 0.5,
    depth_range_m: tuple[float, float] = (500.0, 1200.0),
    transient_amplitude_range: tuple[float, float] = (0.3, 3.0),
) -> ClickScenario:
    """Simulate beaked-whale-like click trains received on bottom-mounted hydrophones.

    Parameters
    ----------
    seed : int
        Seed of every random draw (same seed and options -> identical scenario and audio).
    n_sensors : int, optional
        Hydrophones, 3 to 8. They lie on a jittered ring of radius `array_radius_m` (with one
        near the centre when ``n_sensors >= 5``) at depths 1500–1700 m (z negative).
    n_sources : int, optional
        Whales, 1 to 3. Each starts within ``0.6 * array_radius_m`` of the array centre at a
        depth drawn from `depth_range_m`, moves at a speed drawn from `speed_range_mps` on an arc
        turning at most `max_turn_rate_deg_s`, and drifts vertically by at most 0.2 m/s.
    duration_s : float, optional
        Audio length, s.
    fs : float, optional
        Sample rate, Hz; must exceed twice the highest click and noise frequency.
    snr_db : float, optional
        ``20 log10(A_ref / sigma_band)``: the peak amplitude ``A_ref`` of a nominal
        direct-path click received at `reference_range_m` over the standard deviation
        ``sigma_band`` of the ambient noise within the click band. A click at range ``r`` has
        peak ``(r_ref / r) 10^(-a (r - r_ref) / 20000)`` with ``a`` = `absorption_db_per_km`,
        times the per-click level jitter. ``inf`` gives noise-free audio.
    n_transients : int, optional
        Impulsive false transients, each on one random channel at a uniform random time.
    sound_speed : float, optional
        Constant sound speed, m/s.
    array_radius_m : float, optional
        Radius of the hydrophone ring, m.
    reference_range_m : float, optional
        Range of the SNR definition, m.
    absorption_db_per_km : float, optional
        Frequency-flat absorption, dB/km (about 8 dB/km at 35 kHz in deep water).
    surface_reflection : float, optional
        Pressure reflection coefficient of the surface echo, in ``[-1, 1]`` (0 disables it).
    noise_band_hz : (float, float), optional
        Band of the flat-spectrum ambient noise, Hz; must overlap the click band.
    click : ClickWaveform, optional
        The emitted click (default: 25–45 kHz upsweep, 250 us, Hann taper).
    ici_s, ici_jitter_s : float, optional
        Mean and standard deviation of the inter-click interval, s.
    level_jitter_db : float, optional
        Standard deviation of the per-click source level, dB.
    speed_range_mps, max_turn_rate_deg_s, depth_range_m : optional
        Source motion limits (see `n_sources`).
    transient_amplitude_range : (float, float), optional
        Peak amplitude range of the transients (log-uniform), relative to ``A_ref``.

    Returns
    -------
    ClickScenario

    Raises
    ------
    ValueError
        Any option out of range.

    Notes
    -----
    Emission ``k`` of a source at position ``p_k`` reaches sensor ``s_i`` at
    ``t_e + |p_k - s_i| / c`` (direct path) and at ``t_e + |p_k' - s_i| / c`` with
    ``p_k' = (x, y, -z)`` the image source (surface echo, amplitude scaled by the reflection
    coefficient). The click train starts before the audio so that arrivals are present from
    ``t = 0``; emissions none of whose arrivals fall inside ``[0, duration_s)`` are dropped.

    Examples
    --------
    >>> sc = simulate_clicks(seed=0, n_sensors=4, n_sources=1, duration_s=3.0, snr_db=40.0)
    >>> sc.n_sensors, sc.sources[0].arrival_times.shape[1]
    (4, 4)
    """
    click = ClickWaveform() if click is None else click
    _validate(
        n_sensors=n_sensors, n_sources=n_sources, duration_s=duration_s, fs=fs, snr_db=snr_db,
        n_transients=n_transients, sound_speed=sound_speed, array_radius_m=array_radius_m,
        reference_range_m=reference_range_m, absorption_db_per_km=absorption_db_per_km,
        surface_reflection=surface_reflection, noise_band_hz=noise_band_hz, click=click,
        ici_s=ici_s, ici_jitter_s=ici_jitter_s, level_jitter_db=level_jitter_db,
        speed_range_mps=speed_range_mps, max_turn_rate_deg_s=max_turn_rate_deg_s,
        depth_range_m=depth_range_m, transient_amplitude_range=transient_amplitude_range,
    )
    rng = np.random.default_rng(seed)
    c = float(sound_speed)
    sensors = SensorArray(_layout(n_sensors, rng, radius_m=array_radius_m), c)
    pos_s = sensors.positions
    centre = pos_s[:, :2].mean(axis=0)
    n_samples = int(round(duration_s * fs))
    audio = np.zeros((n_samples, n_sensors), dtype=np.float32)

    def loss(r: NDArray[np.float64]) -> NDArray[np.float64]:
        # spherical spreading and absorption, unit at the reference range
        return (reference_range_m / r) * 10.0 ** (
            -absorption_db_per_km * (r - reference_range_m) / 20_000.0
        )

    tracks = []
    for k in range(n_sources):
        rad = 0.6 * array_radius_m * np.sqrt(rng.uniform())
        phi = rng.uniform(0.0, 2.0 * np.pi)
        p0 = np.array([
            centre[0] + rad * np.cos(phi), centre[1] + rad * np.sin(phi),
            -rng.uniform(*depth_range_m),
        ])
        speed = rng.uniform(*speed_range_mps)
        heading = rng.uniform(0.0, 2.0 * np.pi)
        turn = np.radians(rng.uniform(-max_turn_rate_deg_s, max_turn_rate_deg_s))
        vz = rng.uniform(-0.2, 0.2)
        # start the train early enough that the slowest path at t = 0 is already arriving
        img0 = p0 * np.array([1.0, 1.0, -1.0])
        head_start_s = float(np.linalg.norm(img0 - pos_s, axis=1).max()) / c + click.duration_s
        t_em = draw_emission_times(
            ici_mean_s=ici_s, ici_jitter_s=ici_jitter_s, t_start_s=-head_start_s - ici_s,
            t_end_s=duration_s, rng=rng,
        )
        pos = _positions(t_em, p0, speed, heading, turn, vz)
        img = pos * np.array([1.0, 1.0, -1.0])  # image source across the surface z = 0
        r_dir = np.linalg.norm(pos[:, None, :] - pos_s[None, :, :], axis=2)  # (n_clicks, n_sens)
        r_img = np.linalg.norm(img[:, None, :] - pos_s[None, :, :], axis=2)
        t_dir = t_em[:, None] + r_dir / c
        t_img = t_em[:, None] + r_img / c
        # keep emissions with any arrival overlapping the audio
        first = np.minimum(t_dir.min(axis=1), t_img.min(axis=1) if surface_reflection else np.inf)
        last = np.maximum(t_dir.max(axis=1), t_img.max(axis=1) if surface_reflection else -np.inf)
        half = 0.5 * click.duration_s
        keep = (last + half > 0.0) & (first - half < duration_s)
        t_em, pos, r_dir, r_img, t_dir, t_img = (
            a[keep] for a in (t_em, pos, r_dir, r_img, t_dir, t_img)
        )
        src_amp = 10.0 ** (level_jitter_db * rng.standard_normal(t_em.size) / 20.0)
        a_dir = src_amp[:, None] * loss(r_dir)
        a_img = surface_reflection * src_amp[:, None] * loss(r_img)
        tracks.append(WhaleTrack(
            source_id=k, start_position=p0, speed_mps=float(speed), heading_rad=float(heading),
            turn_rate_rad_s=float(turn), vertical_rate_mps=float(vz), ici_mean_s=float(ici_s),
            ici_jitter_s=float(ici_jitter_s), emission_times=t_em, positions=pos,
            source_amplitudes=src_amp, arrival_times=t_dir, arrival_amplitudes=a_dir,
            echo_arrival_times=t_img, echo_amplitudes=a_img,
        ))
        ch = np.broadcast_to(np.arange(n_sensors), t_dir.shape).ravel()
        _render(audio, t_dir.ravel(), ch, a_dir.ravel(), click.evaluate, half, half, fs)
        if surface_reflection:
            _render(audio, t_img.ravel(), ch, a_img.ravel(), click.evaluate, half, half, fs)

    # impulsive false transients, one channel each
    tr_t = rng.uniform(0.0, duration_s, n_transients)
    tr_ch = rng.integers(0, n_sensors, n_transients)
    lo, hi = np.log(transient_amplitude_range[0]), np.log(transient_amplitude_range[1])
    tr_a = np.exp(rng.uniform(lo, hi, n_transients))
    tr_f = rng.uniform(5_000.0, min(45_000.0, 0.45 * fs), n_transients)
    tr_d = rng.uniform(30e-6, 150e-6, n_transients)
    if n_transients:
        shape = _transient_shape(tr_f[:, None], tr_d[:, None])
        _render(audio, tr_t, tr_ch, tr_a, shape, 0.0, 8.0 * float(tr_d.max()), fs)

    # band-limited ambient noise at the requested in-band SNR
    f_lo, f_hi = noise_band_hz
    overlap = min(f_hi, click.f_end_hz) - max(f_lo, click.f_start_hz)
    noise_std_band = 0.0 if np.isinf(snr_db) else 10.0 ** (-snr_db / 20.0)
    # flat PSD: in-band variance = total variance * overlap / noise bandwidth
    noise_std = noise_std_band * np.sqrt((f_hi - f_lo) / overlap)
    if noise_std > 0:
        _add_band_noise(audio, fs, noise_band_hz, noise_std, rng)

    logger.debug(
        "simulated %d clicks from %d source(s) on %d sensors, %.1f s",
        sum(t.n_clicks for t in tracks), n_sources, n_sensors, duration_s,
    )
    return ClickScenario(
        seed=int(seed), sensors=sensors, fs=float(fs), duration_s=float(duration_s),
        sources=tuple(tracks), audio=audio, click=click, snr_db=float(snr_db),
        reference_range_m=float(reference_range_m), noise_std_band=float(noise_std_band),
        noise_std=float(noise_std), noise_band_hz=(float(f_lo), float(f_hi)),
        absorption_db_per_km=float(absorption_db_per_km),
        surface_reflection=float(surface_reflection), transient_times=tr_t,
        transient_channels=tr_ch, transient_amplitudes=tr_a, transient_freqs_hz=tr_f,
    )


def _validate(**o: Any) -> None:
    def finite_pos(name: str) -> None:
        v = o[name]
        if isinstance(v, bool) or not np.isfinite(v) or v <= 0:
            raise ValueError(f"{name} must be a positive number, got {v!r}")

    def rng_pair(name: str, lo_min: float = 0.0) -> None:
        v = o[name]
        if len(v) != 2 or not all(np.isfinite(x) for x in v) or not lo_min <= v[0] <= v[1]:
            raise ValueError(f"{name} must be (low, high) with {lo_min} <= low <= high, got {v!r}")

    for name, lo, hi in (("n_sensors", 3, 8), ("n_sources", 1, 3)):
        v = o[name]
        if isinstance(v, bool) or int(v) != v or not lo <= v <= hi:
            raise ValueError(f"{name} must be an integer from {lo} to {hi}, got {v!r}")
    n_tr = o["n_transients"]
    if isinstance(n_tr, bool) or int(n_tr) != n_tr or n_tr < 0:
        raise ValueError(f"n_transients must be a non-negative integer, got {n_tr!r}")
    for name in ("duration_s", "fs", "sound_speed", "array_radius_m", "reference_range_m",
                 "ici_s"):
        finite_pos(name)
    if np.isnan(o["snr_db"]) or o["snr_db"] == -np.inf:
        raise ValueError(f"snr_db must be a number or +inf, got {o['snr_db']!r}")
    for name in ("absorption_db_per_km", "ici_jitter_s", "level_jitter_db", "max_turn_rate_deg_s"):
        v = o[name]
        if not np.isfinite(v) or v < 0:
            raise ValueError(f"{name} must be >= 0, got {v!r}")
    if not np.isfinite(o["surface_reflection"]) or abs(o["surface_reflection"]) > 1:
        raise ValueError(f"surface_reflection must be in [-1, 1], got {o['surface_reflection']!r}")
    for name in ("noise_band_hz", "speed_range_mps", "depth_range_m"):
        rng_pair(name)
    rng_pair("transient_amplitude_range", 1e-12)
    click: ClickWaveform = o["click"]
    f_lo, f_hi = o["noise_band_hz"]
    nyq = 0.5 * o["fs"]
    if click.f_end_hz >= nyq or f_hi >= nyq:
        raise ValueError(
            f"fs={o['fs']} Hz is too low: the click band ends at {click.f_end_hz} Hz and the "
            f"noise band at {f_hi} Hz, both must stay below fs/2"
        )
    if min(f_hi, click.f_end_hz) - max(f_lo, click.f_start_hz) <= 0:
        raise ValueError(f"noise_band_hz {o['noise_band_hz']} does not overlap the click band")
    if o["depth_range_m"][0] <= 0:
        raise ValueError(f"depth_range_m must be positive depths, got {o['depth_range_m']!r}")


# --------------------------------------------------------------------------------------------
# files
# --------------------------------------------------------------------------------------------
def truth_document(scenario: ClickScenario, *, audio_scale: float = 1.0) -> dict[str, Any]:
    """The ground truth of a scenario as a JSON-serialisable dict (the ``truth.json`` layout).

    Parameters
    ----------
    scenario : ClickScenario
        The scenario.
    audio_scale : float, optional
        Factor from scenario units to the samples of the written audio file.

    Returns
    -------
    dict
        Keys ``kind, seed, fs, duration_s, sound_speed, audio_scale, snr_db, reference_range_m,
        noise_std_band, noise_std, noise_band_hz, absorption_db_per_km, surface_reflection,
        click, pairs, sources, transients``. Each source holds ``emission_times`` (n,),
        ``positions`` (n, 3), ``arrival_times``/``echo_arrival_times`` (n, n_sensors),
        ``arrival_amplitudes``/``echo_amplitudes`` (n, n_sensors) and ``tdoas`` (n, n_pairs:
        ``t_i - t_j`` for each pair of ``pairs``, direct path). Amplitudes are in scenario
        units; multiply by ``audio_scale`` for file units. ``snr_db`` is ``null`` for
        noise-free audio.
    """
    pairs = scenario.pairs()
    sources = []
    for s in scenario.sources:
        sources.append({
            "id": s.source_id,
            "start_position": s.start_position,
            "speed_mps": s.speed_mps,
            "heading_rad": s.heading_rad,
            "turn_rate_rad_s": s.turn_rate_rad_s,
            "vertical_rate_mps": s.vertical_rate_mps,
            "ici_mean_s": s.ici_mean_s,
            "ici_jitter_s": s.ici_jitter_s,
            "emission_times": s.emission_times,
            "positions": s.positions,
            "source_amplitudes": s.source_amplitudes,
            "arrival_times": s.arrival_times,
            "arrival_amplitudes": s.arrival_amplitudes,
            "echo_arrival_times": s.echo_arrival_times,
            "echo_amplitudes": s.echo_amplitudes,
            "tdoas": s.tdoas(pairs),
        })
    return {
        "kind": "clicks",
        "seed": scenario.seed,
        "fs": scenario.fs,
        "duration_s": scenario.duration_s,
        "sound_speed": scenario.sensors.sound_speed,
        "audio_scale": float(audio_scale),
        "snr_db": scenario.snr_db if np.isfinite(scenario.snr_db) else None,
        "reference_range_m": scenario.reference_range_m,
        "noise_std_band": scenario.noise_std_band,
        "noise_std": scenario.noise_std,
        "noise_band_hz": list(scenario.noise_band_hz),
        "absorption_db_per_km": scenario.absorption_db_per_km,
        "surface_reflection": scenario.surface_reflection,
        "click": {
            "f_start_hz": scenario.click.f_start_hz,
            "f_end_hz": scenario.click.f_end_hz,
            "duration_s": scenario.click.duration_s,
            "taper": "hann",
        },
        "pairs": [list(p) for p in pairs],
        "sources": sources,
        "transients": [
            {"time": float(t), "channel": int(ch), "amplitude": float(a), "freq_hz": float(f)}
            for t, ch, a, f in zip(
                scenario.transient_times, scenario.transient_channels,
                scenario.transient_amplitudes, scenario.transient_freqs_hz, strict=True,
            )
        ],
    }


def write_click_scenario(out_dir: Path | str, scenario: ClickScenario) -> list[Path]:
    """Write a scenario as ``audio.flac``, ``array.json``, ``truth.json`` and ``tdoa_labels.csv``.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created if missing).
    scenario : ClickScenario
        The scenario.

    Returns
    -------
    list of pathlib.Path
        The written files.

    Notes
    -----
    ``tdoa_labels.csv`` (``time,i,j,tau,source``) holds the direct-path TDOA of every click and
    sensor pair, the labels ``fusion train-validator`` takes: ``time`` is the click's arrival at
    sensor ``i``, ``tau`` its arrival at ``i`` minus at ``j``, s. FLAC holds 24-bit integers in
    ``[-1, 1)``: the audio is scaled so its largest magnitude is :data:`FILE_PEAK` and the
    factor is stored as ``truth.json["audio_scale"]`` (file sample = ``audio_scale`` x scenario
    value). Every file is written atomically.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: output path exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    peak = float(np.max(np.abs(scenario.audio))) if scenario.audio.size else 0.0
    scale = FILE_PEAK / peak if peak > 0 else 1.0
    audio_path = write_audio(out / "audio.flac", scenario.audio * np.float32(scale), scenario.fs)
    array_path = write_array(out / "array.json", scenario.sensors)
    truth_path = write_json(out / "truth.json", truth_document(scenario, audio_scale=scale))
    cols: dict[str, list[NDArray]] = {"time": [], "i": [], "j": [], "tau": [], "source": []}
    for src in scenario.sources:
        arr = src.arrival_times
        for i, j in scenario.pairs():
            n = arr.shape[0]
            for key, v in (("time", arr[:, i]), ("i", np.full(n, i)), ("j", np.full(n, j)),
                           ("tau", arr[:, i] - arr[:, j]), ("source", np.full(n, src.source_id))):
                cols[key].append(v)
    labels = {k: np.concatenate(v) if v else np.empty(0) for k, v in cols.items()}
    order = np.argsort(labels["time"], kind="stable")
    labels_path = write_table(out / "tdoa_labels.csv",
                              {k: (v[order].astype(int) if k in ("i", "j", "source") else v[order])
                               for k, v in labels.items()}, float_format="%.9f")
    logger.info("wrote click scenario (seed %d) to %s", scenario.seed, out)
    return [audio_path, array_path, truth_path, labels_path]


def write_scenario(out_dir: Path, *, seed: int) -> list[Path]:
    """``fusion simulate clicks``: the default scenario (:func:`simulate_clicks`) written out.

    Parameters
    ----------
    out_dir : pathlib.Path
        Output folder.
    seed : int
        Scenario seed.

    Returns
    -------
    list of pathlib.Path
        ``audio.flac`` (96 kHz, channel i = sensor i), ``array.json``, ``truth.json``.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: output path exists and is not a folder")
    return write_click_scenario(out, simulate_clicks(seed=seed))
