"""Data of the click-scenario simulator: the click waveform, one source's track, the scenario.

The simulator itself is :func:`fusion.simulate.clicks.simulate_clicks`; these names are
importable from :mod:`fusion.simulate.clicks` too.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.geometry import SensorArray
from fusion.simulate.whale_range.synthesis import _positions
from fusion.types import frozen_array

__all__ = ["ClickScenario", "ClickWaveform", "WhaleTrack"]



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
    bottom_echo_arrival_times, bottom_echo_amplitudes : ndarray, shape (n_clicks, n_sensors)
        The sea-floor echo (range world with a floor only; None otherwise).
    click : ClickWaveform or None
        This whale's click (None: the scenario's click).
    source_level_db : float
        This whale's level offset from the nominal source level, dB (included in
        `source_amplitudes`).
    effective_speeds : dict or None
        ``{"direct"|"surface"|"bottom": (n_clicks, n_sensors)}``: path length over travel time,
        m/s (range world only).
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
    bottom_echo_arrival_times: NDArray[np.float64] | None = None
    bottom_echo_amplitudes: NDArray[np.float64] | None = None
    click: ClickWaveform | None = None
    source_level_db: float = 0.0
    effective_speeds: dict[str, NDArray[np.float64]] | None = None

    def __post_init__(self) -> None:
        for name in (
            "start_position", "emission_times", "positions", "source_amplitudes",
            "arrival_times", "arrival_amplitudes", "echo_arrival_times", "echo_amplitudes",
            "bottom_echo_arrival_times", "bottom_echo_amplitudes",
        ):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, frozen_array(getattr(self, name)))
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
    world : RangeWorld or None
        The bottom-mounted-range physics (floor, profile, true sensor positions, reflection
        coefficients, interferers) when any range option was given; None for the default
        scenario. With a world, `sensors` holds the *surveyed* positions and the nominal speed
        (what ``array.json`` says), ``world.sensors_true`` the true ones.
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
    transient_times: NDArray[np.float64] = field(default_factory=lambda: frozen_array([]))
    transient_channels: NDArray[np.int64] = field(default_factory=lambda: frozen_array([], int))
    transient_amplitudes: NDArray[np.float64] = field(default_factory=lambda: frozen_array([]))
    transient_freqs_hz: NDArray[np.float64] = field(default_factory=lambda: frozen_array([]))
    world: Any = None

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
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        object.__setattr__(self, "transient_channels", frozen_array(self.transient_channels, int))

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
