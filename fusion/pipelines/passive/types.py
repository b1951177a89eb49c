"""Data of the passive pipeline: scans and clicks in, per-scan results and smoothed tracks out.

All are frozen dataclasses. Angles are degrees and times seconds in these records (as in the
files they become); inside the parts, radians.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.passive.crossing import CrossingAlert
from fusion.passive.quality import LABELS
from fusion.pipelines.passive.crossing import CrossingResolution
from fusion.types import Cube

__all__ = [
    "Click",
    "SmootherSettings",
    "PassiveResult",
    "PassiveTrack",
    "Scan",
    "ScanResult",
    "TrackEnd",
    "TrackStart",
    "TrackUpdate",
    "scans_of",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Scan:
    """One beam/frequency scan of a line array.

    Attributes
    ----------
    power : ndarray, shape (n_beams, n_bins)
        Power, linear, normalised so that noise alone has mean 1; beams equally spaced in cosine
        from forward endfire.
    time : float
        Scan time, s.
    freqs, scan_period, aperture, sound_speed
        Those of the cube the scan belongs to (:class:`fusion.types.Cube`).
    """

    power: FloatArray
    time: float
    freqs: FloatArray
    scan_period: float
    aperture: float
    sound_speed: float = 1500.0

    def __post_init__(self) -> None:
        p = np.asarray(self.power, dtype=float)
        f = np.asarray(self.freqs, dtype=float).reshape(-1)
        if p.ndim != 2 or p.shape[0] < 2 or p.shape[1] != f.size:
            raise ValueError(f"scan power must have shape (beams >= 2, {f.size} bins), got {p.shape}")
        if not (np.isfinite(self.time) and np.all(np.isfinite(p))):
            raise ValueError("scan time and power must be finite")
        for name in ("scan_period", "aperture", "sound_speed"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive, got {v!r}")
        object.__setattr__(self, "power", p)
        object.__setattr__(self, "freqs", f)
        object.__setattr__(self, "time", float(self.time))

    @property
    def n_beams(self) -> int:
        """Number of beams."""
        return int(self.power.shape[0])


def scans_of(cubes: Cube | Sequence[Cube]) -> Iterator[Scan]:
    """The scans of one cube or of consecutive cubes of one recording, in time order.

    Scan ``k`` of the sequence (counted over all cubes) has time ``k * scan_period``; the cubes
    must share beams, frequencies, scan period, aperture and sound speed.
    """
    seq = [cubes] if isinstance(cubes, Cube) else list(cubes)
    if not seq:
        raise ValueError("no cube given")
    first = seq[0]
    k = 0
    for i, c in enumerate(seq):
        if (c.n_beams != first.n_beams or c.n_bins != first.n_bins
                or not np.allclose(c.freqs, first.freqs)
                or not np.isclose(c.scan_period, first.scan_period)
                or not np.isclose(c.aperture, first.aperture)
                or not np.isclose(c.sound_speed, first.sound_speed)):
            raise ValueError(f"cube {i} does not continue cube 0 (beams, bins, frequencies, scan "
                             "period, aperture and sound speed must match)")
        for p in c.power:
            yield Scan(power=p, time=k * first.scan_period, freqs=first.freqs,
                       scan_period=first.scan_period, aperture=first.aperture,
                       sound_speed=first.sound_speed)
            k += 1


@dataclass(frozen=True)
class Click:
    """An operator's click on a line.

    Attributes
    ----------
    beam : int
        Clicked beam.
    freq_hz : float
        Clicked frequency, Hz.
    time : float, optional
        Time of the click, s; None: as soon as the acquisition window is full.
    """

    beam: int
    freq_hz: float
    time: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.beam, bool) or int(self.beam) != self.beam or self.beam < 0:
            raise ValueError(f"click beam must be a non-negative integer, got {self.beam!r}")
        if not (np.isfinite(self.freq_hz) and self.freq_hz > 0):
            raise ValueError(f"click frequency must be positive, got {self.freq_hz!r}")
        if self.time is not None and not np.isfinite(self.time):
            raise ValueError(f"click time must be finite, got {self.time!r}")
        object.__setattr__(self, "beam", int(self.beam))


@dataclass(frozen=True)
class SmootherSettings:
    """Settings of the tracks' fixed-lag graphs and of their crossing episodes.

    Attributes
    ----------
    lag_s : float
        Fixed lag, s; must hold a crossing episode and its context.
    accel_sigma_deg_per_min2 : float
        Bearing-acceleration standard deviation per scan, deg/min^2; the PSD of the white-noise-
        acceleration model is ``q = sigma_a^2 T`` (T the scan period).
    beam_sigma : float
        Standard deviation of a measured peak, beams.
    gate : float
        Innovation gate of a measurement, standard deviations.
    uncertain_q_factor : float
        Process-noise scale of a step whose TQI is ``uncertain``.
    block : int
        Scans of states that leave the lag together (see `block_s` of
        :class:`~fusion.passive.smoothing.fixed_lag.FixedLagBearingTrack`).
    context_scans : int
        Own bearings of each track, from before a crossing episode, given to the multi-track
        graph to tell the tracks apart.
    separation_lobes : float
        Half a crossing episode: the time for the pair to draw this many main lobes apart.
    """

    lag_s: float = 200.0
    accel_sigma_deg_per_min2: float = 2.0
    beam_sigma: float = 0.5
    gate: float = 4.0
    uncertain_q_factor: float = 10.0
    block: int = 10
    context_scans: int = 20
    separation_lobes: float = 1.5

    def __post_init__(self) -> None:
        for name in ("lag_s", "accel_sigma_deg_per_min2", "beam_sigma", "gate",
                     "uncertain_q_factor", "separation_lobes"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be finite and > 0, got {v!r}")
        for name in ("block", "context_scans"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")


@dataclass(frozen=True)
class TrackStart:
    """A track started from an acquisition.

    Attributes
    ----------
    track_id : int
        New track's id.
    time : float
        Time of its first state (the acquisition's latest scan), s.
    source : str
        ``"click"`` or ``"auto"``.
    beam : int
        Clicked (or proposed) beam.
    freq_hz : float
        Centre of the track's bin, Hz.
    bearing_deg, bearing_rate_deg_per_min : float
        The acquisition's estimate: the prior mean.
    sigma_bearing_deg, sigma_rate_deg_per_min : float
        The prior's standard deviations.
    snr_db : float
        The acquisition's SNR in 1 Hz, dB.
    default_used : bool
        Whether the acquisition output its defaults.
    """

    track_id: int
    time: float
    source: str
    beam: int
    freq_hz: float
    bearing_deg: float
    bearing_rate_deg_per_min: float
    sigma_bearing_deg: float
    sigma_rate_deg_per_min: float
    snr_db: float
    default_used: bool


@dataclass(frozen=True)
class TrackEnd:
    """A track ended by the track quality indicator.

    Attributes
    ----------
    track_id : int
        The track.
    time : float
        Time of its last state, s (the update at which the TQI said ``lost``).
    """

    track_id: int
    time: float


@dataclass(frozen=True)
class TrackUpdate:
    """A live track after one scan (its filtered state: the latest of its fixed-lag graph).

    Attributes
    ----------
    track_id : int
        The track.
    time : float
        Scan time, s.
    bearing_deg, bearing_rate_deg_per_min : float
        Latest state, deg and deg/min.
    sigma_bearing_deg, sigma_rate_deg_per_min : float
        Its marginal standard deviations.
    tqi : str
        Track quality after this update: ``lost``, ``uncertain``, ``low_snr`` or ``strong``.
    amplitude : float
        Power of the predicted cell (TQI input), linear, normalised.
    residual_deg : float
        Measured minus predicted bearing (TQI input), deg.
    measured : bool
        Whether a bearing entered the track's graph at this scan (False: gated out, coasting
        through a crossing episode, or the last update of a lost track).
    in_crossing : bool
        Whether the track is in a crossing episode.
    """

    track_id: int
    time: float
    bearing_deg: float
    bearing_rate_deg_per_min: float
    sigma_bearing_deg: float
    sigma_rate_deg_per_min: float
    tqi: str
    amplitude: float
    residual_deg: float
    measured: bool
    in_crossing: bool


@dataclass(frozen=True)
class ScanResult:
    """Everything the pipeline did at one scan.

    Attributes
    ----------
    time : float
        Scan time, s.
    updates : tuple of TrackUpdate
        Live tracks after the scan (tracks ended at this scan included, with ``tqi="lost"``).
    starts : tuple of TrackStart
        Tracks started at this scan.
    ends : tuple of TrackEnd
        Tracks ended at this scan.
    alerts : tuple of CrossingAlert
        Crossing alerts raised at this scan.
    resolutions : tuple of CrossingResolution
        Crossing episodes resolved at this scan.
    """

    time: float
    updates: tuple[TrackUpdate, ...]
    starts: tuple[TrackStart, ...]
    ends: tuple[TrackEnd, ...]
    alerts: tuple[CrossingAlert, ...]
    resolutions: tuple[CrossingResolution, ...]


@dataclass(frozen=True)
class PassiveTrack:
    """A smoothed track.

    Attributes
    ----------
    track_id : int
        The track.
    time : ndarray, shape (n,)
        State times, s.
    bearing_deg, bearing_rate_deg_per_min : ndarray, shape (n,)
        Fixed-lag smoothed states, deg and deg/min.
    sigma_bearing_deg, sigma_rate_deg_per_min : ndarray, shape (n,)
        Their marginal standard deviations.
    tqi : ndarray of str, shape (n,)
        Track quality at each state (``""`` at the first state, before any update).
    freq_hz : float
        Centre of the track's bin, Hz.
    start : TrackStart
        How the track started.
    end : TrackEnd or None
        How it ended (None: alive at the end of the data).
    """

    track_id: int
    time: FloatArray
    bearing_deg: FloatArray
    bearing_rate_deg_per_min: FloatArray
    sigma_bearing_deg: FloatArray
    sigma_rate_deg_per_min: FloatArray
    tqi: NDArray[np.str_]
    freq_hz: float
    start: TrackStart
    end: TrackEnd | None

    def __len__(self) -> int:
        return int(self.time.shape[0])


@dataclass(frozen=True)
class PassiveResult:
    """Output of a pipeline run.

    Attributes
    ----------
    tracks : tuple of PassiveTrack
        Every track, by id.
    alerts : tuple of CrossingAlert
        Every crossing alert, in time order.
    resolutions : tuple of CrossingResolution
        Every resolved crossing episode.
    n_scans : int
        Scans processed.
    """

    tracks: tuple[PassiveTrack, ...]
    alerts: tuple[CrossingAlert, ...]
    resolutions: tuple[CrossingResolution, ...]
    n_scans: int

    def track_columns(self) -> dict[str, NDArray]:
        """Columns of the tracks file: ``track_id,time,bearing_deg,bearing_rate_deg_per_min,
        sigma_bearing_deg,tqi`` (one row per track per state)."""
        trs = self.tracks
        cat = (lambda xs, dt: np.concatenate(xs) if xs else np.zeros(0, dt))  # noqa: E731
        return {
            "track_id": cat([np.full(len(t), t.track_id, np.int64) for t in trs], np.int64),
            "time": cat([t.time for t in trs], float),
            "bearing_deg": cat([t.bearing_deg for t in trs], float),
            "bearing_rate_deg_per_min": cat([t.bearing_rate_deg_per_min for t in trs], float),
            "sigma_bearing_deg": cat([t.sigma_bearing_deg for t in trs], float),
            "tqi": cat([t.tqi for t in trs], LABELS.dtype),
        }

    def alert_columns(self) -> dict[str, NDArray]:
        """Columns of the alerts file (``time,track_a,track_b,t_cross,kind``)."""
        a = self.alerts
        return {
            "time": np.array([x.time for x in a], float),
            "track_a": np.array([x.track_a for x in a], np.int64),
            "track_b": np.array([x.track_b for x in a], np.int64),
            "t_cross": np.array([x.t_cross for x in a], float),
            "kind": np.array([x.kind.value for x in a], dtype="<U9"),
        }
