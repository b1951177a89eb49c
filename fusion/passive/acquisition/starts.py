"""Automatic track starts: :class:`LineStarter` proposes the strongest lines no track holds.

Local peaks of the recent mean beam/frequency history (a gamma-quantile threshold for noise
alone), outside the exclusion zone of every held line; a candidate still passes the acquisition
(:mod:`fusion.passive.acquisition.acquire`) before a track starts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from fusion._validation import check_positive

__all__ = ["LineStarter", "StartCandidate"]

FloatArray = NDArray[np.float64]


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

    def excluded(
        self, beam: float, bin: int, *, held: list[tuple[float, int]], lobe_beams: FloatArray
    ) -> bool:
        """Whether the cell ``(beam, bin)`` lies in the exclusion zone of a held line.

        Parameters
        ----------
        beam : float
            Beam, possibly fractional (an acquisition's estimate).
        bin : int
            Frequency bin.
        held : list of (float, int)
            ``(beam, bin)`` of every line held.
        lobe_beams : ndarray, shape (n_bins,)
            Main-lobe width of each bin in beams.
        """
        reach = self.exclusion_lobes * float(lobe_beams[bin])
        return any(abs(beam - hb) <= reach and abs(bin - hf) <= self.bin_guard for hb, hf in held)

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
            if self.excluded(b, f, held=taken, lobe_beams=lobe_beams):
                continue
            out.append(StartCandidate(beam=b, bin=f, mean_power=float(mean[b, f])))
            taken.append((float(b), f))
            if len(out) == self.max_starts:
                break
        return out
