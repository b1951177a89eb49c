"""Parts of the passive pipeline that read the cube: a track's bearing measurement, automatic starts.

- :class:`PeakMeasurer` measures one track in one scan: the power of the cell at the predicted
  beam (the tracker amplitude ``A(k)`` of the track quality indicator), the peak near the
  predicted beam refined by a power-weighted centroid, and its bearing residual; the narrowband
  tracker's measurement step (:mod:`fusion.passive.tracker`, steps 2-5) for one scan at a time.
- :class:`LineStarter` proposes automatic track starts from the strongest lines of the recent
  beam/frequency history that no track holds.

Beams are equally spaced in cosine (beam 0 at forward endfire); bearings are cone angles in
``[0, pi]``.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from fusion._validation import check_positive
from fusion.geometry import beam_from_bearing, bearing_from_beam

__all__ = ["BearingMeasurement", "LineStarter", "PeakMeasurer", "StartCandidate"]

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class BearingMeasurement:
    """One track's measurement in one scan.

    Attributes
    ----------
    amplitude : float
        Power of the cell at the predicted beam, linear, normalised (noise mean 1).
    bearing : float
        Measured bearing, rad (centroid of the peak near the predicted beam).
    beam : float
        Fractional beam of the measured bearing.
    peak_power : float
        Power of the peak cell, linear.
    sigma : float
        Standard deviation of the measured bearing, rad.
    residual_deg : float
        Measured minus predicted bearing, deg (the error residual ``ES`` of the TQI).
    local_peak : bool
        Whether the strongest beam of the search is a local maximum of the row (False when it is
        at the edge of the search with stronger power just outside: the flank of a line beyond
        the search, not a line within it).
    """

    amplitude: float
    bearing: float
    beam: float
    peak_power: float
    sigma: float
    residual_deg: float
    local_peak: bool


class PeakMeasurer:
    """Bearing measurement near a predicted bearing in one beam row of a scan.

    Parameters
    ----------
    beam_sigma : float
        Standard deviation of the centroid, beams; mapped to bearing through
        ``dtheta/db = 2 / ((N - 1) sin theta)`` with the sine floored half a beam off endfire.
    noise_mean : float
        Mean noise power of the normalised spectra (subtracted in the centroid weights).

    Notes
    -----
    The measurement of the narrowband bearing tracker (:class:`fusion.passive.tracker.
    BearingTracker`, module steps 2-5) for one scan: amplitude at the nearest beam to
    ``b = (N - 1)(1 - cos theta) / 2`` (eq. 5 of the acquisition text), the strongest beam within
    ``search_beams`` of it, and the centroid of that beam and its two neighbours above the noise
    mean. Added: whether that beam is a local maximum of the row, so that the flank of a stronger
    line just outside the search is not taken for the track's line.
    """

    def __init__(self, *, beam_sigma: float = 0.5, noise_mean: float = 1.0) -> None:
        self.beam_sigma = check_positive("beam_sigma", beam_sigma)
        self.noise_mean = check_positive("noise_mean", noise_mean)

    def sigma(self, bearing: float, n_beams: int) -> float:
        """Bearing standard deviation of a measurement at `bearing` (rad), rad."""
        sin_floor = math.sin(float(bearing_from_beam(0.5, n_beams)))
        s = max(math.sin(min(max(bearing, 0.0), math.pi)), sin_floor)
        return self.beam_sigma * 2.0 / ((n_beams - 1) * s)

    def measure(
        self, row: FloatArray, predicted_bearing: float, *, search_beams: int
    ) -> BearingMeasurement:
        """Measure the line near `predicted_bearing` in one row of beam powers.

        Parameters
        ----------
        row : ndarray, shape (n_beams,)
            Normalised power of the track's band in every beam at this scan.
        predicted_bearing : float
            Predicted bearing, rad (clipped to ``[0, pi]``).
        search_beams : int
            Half-width of the peak search, beams.

        Returns
        -------
        BearingMeasurement
        """
        n_beams = row.shape[0]
        theta_pred = min(max(float(predicted_bearing), 0.0), math.pi)
        ib = int(min(max(math.floor(float(beam_from_bearing(theta_pred, n_beams)) + 0.5), 0),
                     n_beams - 1))
        amp = float(row[ib])  # A(k): the predicted cell, before the scan is searched
        lo, hi = max(ib - search_beams, 0), min(ib + search_beams, n_beams - 1)
        peak = lo + int(np.argmax(row[lo:hi + 1]))
        local = not ((peak == lo and lo > 0 and row[lo - 1] > row[lo])
                     or (peak == hi and hi < n_beams - 1 and row[hi + 1] > row[hi]))
        cells = np.clip(np.arange(peak - 1, peak + 2), 0, n_beams - 1)
        w = np.maximum(row[cells] - self.noise_mean, 0.0)
        total = float(w.sum())
        beam = float(np.dot(w, cells) / total) if total > 0 else float(peak)
        theta = float(bearing_from_beam(beam, n_beams))
        return BearingMeasurement(
            amplitude=amp, bearing=theta, beam=beam, peak_power=float(row[peak]),
            sigma=self.sigma(theta_pred, n_beams),
            residual_deg=math.degrees(theta - theta_pred), local_peak=local,
        )


@dataclass(frozen=True)
class StartCandidate:
    """A line proposed for an automatic start.

    Attributes
    ----------
    beam : int
        Beam of the peak.
    bin : int
        Frequency bin of the peak.
    mean_power : float
        Mean power of the cell over the starter's window (noise mean 1).
    """

    beam: int
    bin: int
    mean_power: float


class LineStarter:
    """Automatic starts: local peaks of the recent mean BTR of each bin that no track holds.

    Parameters
    ----------
    window_scans : int
        Scans averaged into the mean BTR (the latest ones).
    every_scans : int
        Scans between two looks for new lines.
    false_alarm : float
        Probability that a noise-only cell's mean exceeds the threshold.
    noise_dof : float
        Degrees of freedom of one cell's noise (2: one periodogram look).
    max_starts : int
        Most candidates proposed per look (strongest first).
    exclusion_lobes : float
        Main-lobe widths, in beams, around a held or accepted line in which no candidate is
        proposed (2 covers the first sidelobes of a strong line).
    bin_guard : int
        Bins on each side of a held line's bins that the exclusion also covers.

    Notes
    -----
    The rule: a cell ``(beam, bin)`` is a candidate when its mean over the last
    `window_scans` scans (normalised power, noise mean 1) is a local maximum across beams and
    bins, exceeds the threshold, and lies outside the exclusion zone of every held line. For
    noise alone the mean of ``W`` cells of ``nu`` degrees of freedom is gamma distributed with
    shape ``W nu / 2`` and mean 1, so the threshold is its upper `false_alarm` quantile. A
    candidate still has to pass the acquisition (its IBW SNR above the acquisition's default
    threshold) before a track starts.
    """

    def __init__(
        self,
        *,
        window_scans: int = 30,
        every_scans: int = 10,
        false_alarm: float = 1e-4,
        noise_dof: float = 2.0,
        max_starts: int = 4,
        exclusion_lobes: float = 2.0,
        bin_guard: int = 1,
    ) -> None:
        for name, v, least in (("window_scans", window_scans, 2), ("every_scans", every_scans, 1),
                               ("max_starts", max_starts, 1), ("bin_guard", bin_guard, 0)):
            if int(v) != v or v < least:
                raise ValueError(f"{name} must be an integer >= {least}, got {v!r}")
        if not 0.0 < false_alarm < 1.0:
            raise ValueError(f"false_alarm must lie in (0, 1), got {false_alarm!r}")
        self.window_scans = int(window_scans)
        self.every_scans = int(every_scans)
        self.false_alarm = float(false_alarm)
        self.noise_dof = check_positive("noise_dof", noise_dof)
        self.max_starts = int(max_starts)
        self.exclusion_lobes = check_positive("exclusion_lobes", exclusion_lobes)
        self.bin_guard = int(bin_guard)
        shape = self.window_scans * self.noise_dof / 2.0
        #: Threshold on the mean BTR (noise mean 1).
        self.threshold = float(stats.gamma.isf(self.false_alarm, shape, scale=1.0 / shape))

    def candidates(
        self,
        history: FloatArray,
        *,
        held: list[tuple[float, int]],
        lobe_beams: FloatArray,
    ) -> list[StartCandidate]:
        """Cells where a new line may start.

        Parameters
        ----------
        history : ndarray, shape (n_scans, n_beams, n_bins)
            Recent normalised scans, the latest last (at least `window_scans`).
        held : list of (float, int)
            ``(beam, bin)`` of every line already held by a track.
        lobe_beams : ndarray, shape (n_bins,)
            Main-lobe width of each bin in beams.

        Returns
        -------
        list of StartCandidate
            Strongest first, at most `max_starts`, each outside the others' exclusion zones.
        """
        if history.ndim != 3 or history.shape[0] < self.window_scans:
            raise ValueError(f"history must hold >= {self.window_scans} scans of (beams, bins), "
                             f"got shape {history.shape}")
        mean = history[-self.window_scans:].mean(axis=0)  # (beams, bins)
        pad = np.pad(mean, 1, mode="constant", constant_values=-np.inf)
        c = pad[1:-1, 1:-1]
        peak = ((c >= pad[:-2, 1:-1]) & (c >= pad[2:, 1:-1]) & (c >= pad[1:-1, :-2])
                & (c >= pad[1:-1, 2:]) & (c > self.threshold))
        beams, bins = np.nonzero(peak)
        order = np.argsort(-mean[beams, bins], kind="stable")
        taken = list(held)
        out: list[StartCandidate] = []
        for b, f in zip(beams[order].tolist(), bins[order].tolist(), strict=True):
            reach = self.exclusion_lobes * float(lobe_beams[f])
            if any(abs(b - hb) <= reach and abs(f - hf) <= self.bin_guard for hb, hf in taken):
                continue
            out.append(StartCandidate(beam=b, bin=f, mean_power=float(mean[b, f])))
            taken.append((float(b), f))
            if len(out) == self.max_starts:
                break
        return out
