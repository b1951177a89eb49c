"""The acquisition component (program segments 22-54): a clicked target's bearing, rate and SNR.

:class:`Acquisition` chains the steps of the method, one module each: normalisation
(:mod:`~fusion.passive.acquisition.normalise`), the IBW BTR (:mod:`~fusion.passive.acquisition.btr`),
beamwidth and beam tolerance (:mod:`fusion.geometry`), the fan search through the anchor beams
(a :class:`~fusion.passive.acquisition.fans.FanStrategy`), the band noise level, IBW SNR and
defaults (:mod:`~fusion.passive.acquisition.snr`), the line's refinement and segment 54 (beam to
bearing, bearing rate, lag correction).
"""

from __future__ import annotations

import logging
import math
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from fusion.geometry import beam_tolerance, beamwidth_deg, bearing_from_beam
from fusion.passive.acquisition.btr import ibw_bins, ibw_btr
from fusion.passive.acquisition.fans import (
    BestLine,
    ConstantRateFans,
    FanStrategy,
    StraightLineFans,
)
from fusion.passive.acquisition.normalise import estimate_noise_dof, normalize_spectra
from fusion.passive.acquisition.result import AcquisitionResult
from fusion.passive.acquisition.snr import band_noise_level, snr_1hz_db
from fusion.types import Cube

__all__ = ["Acquisition", "AcquisitionResult", "acquire"]

logger = logging.getLogger(__name__)


class _BandView:
    """Normalised power of some bins, indexed by a band of cube bin indices."""

    def __init__(self, power: NDArray[np.float64], bins: NDArray[np.intp]) -> None:
        self.power = power
        self.column = {int(b): i for i, b in enumerate(bins)}

    def __getitem__(self, band: NDArray[np.intp]) -> NDArray[np.float64]:
        return self.power[:, :, [self.column[int(b)] for b in band]]


class Acquisition:
    """Estimate a clicked target's bearing, bearing rate and SNR from the best line on its IBW BTR.

    Parameters
    ----------
    ibw_hz : float, optional
        Width of the initialisation band, Hz; None (default) uses the clicked bin alone.
    lag_s : float
        Delay between what the spectra show and the present, s (spectral integration, about half
        an integration period, plus any display delay); the bearing is corrected by
        ``rate * lag_s``. Default 0.
    normalize : bool
        Normalise the IBW bins (program segment 22) with :func:`normalize_spectra`; set False for
        cubes already normalised to unit noise mean.
    window_bins, gap_bins : int
        Split window of the normaliser (bins each side, bins left out each side).
    pool_scans : int, optional
        Scans pooled into each noise estimate of the normaliser (None: the whole history).
    noise_dof : float, optional
        Degrees of freedom of the noise in one cell, for the normaliser (2 for one periodogram
        look); None (default): estimated from the cube's cells away from the click
        (:func:`~fusion.passive.acquisition.normalise.estimate_noise_dof`; 2 when the cube has
        fewer than 3 scans or no bin away from the click).
    trace : {"bearing", "beam"}
        Lines of the fans: constant-bearing-rate traces in the cosine beam spacing (default, see
        :func:`constant_rate_traces`) or the method's literal straight lines in beam number.
    sampling : {"nearest", "linear"}
        How a constant-bearing-rate trace reads the BTR: the nearest beam (the method's rounding,
        default) or linear interpolation across beams.
    refine : bool, optional
        Refine the overall best trace to sub-beam end position and rate (:func:`refine_trace`).
        None (default): True for ``trace="bearing"``; the literal straight lines are never refined.
    refine_span_beams : float
        Half-size of the refinement's search box, beams (see :func:`refine_trace`).
    min_scans : int, optional
        The method's ``minscan``: fewest scans a line may span before it leaves the BTR. None
        (default) uses all scans, as the method text does.
    max_rate_deg_per_min : float, optional
        ``trace="bearing"``: largest bearing-rate magnitude searched, deg/min; None: 180 deg over
        ``min_scans - 1`` scans (the analogue of a line crossing all beams).
    rate_step_deg_per_min : float, optional
        ``trace="bearing"``: bearing-rate increment, deg/min; None: the increment that moves a
        broadside trace's oldest scan by a quarter of a beam, ``0.25 / ((N - 1) / 2 * history)``
        rad/s (the straight lines' quarter beam over the history).
    max_slope : float, optional
        ``trace="beam"``: largest slope magnitude searched, beams per update; None: the slope that
        crosses all beams in ``min_scans`` scans, ``(n_beams - 1) / (min_scans - 1)``.
    slope_step : float, optional
        ``trace="beam"``: slope increment, beams per update; None: a quarter of a beam over the
        history, ``0.25 / (n_scans - 1)``.
    rate_at : {"midpoint", "latest"}
        ``trace="beam"``: beam at which the beam rate is turned into a bearing rate (eq. 10): the
        middle of the best line (default) or its latest end.
    min_snr_ibw : float
        Defaults are output when the linear IBW SNR is at most this (the method: 1, i.e. 0 dB).
    default_snr_ibw : float
        Linear IBW SNR put through eq. 4 to give the default SNR (the method: the threshold).
    exclude_beams : float, optional
        Beams each side of the best line left out of the band noise level; None: the main lobe to
        its first nulls, ``ceil(lambda / L / (2 / (N - 1)))``, at least the beam tolerance.
    fans : FanStrategy, optional
        The fans' lines as a strategy object (:class:`~fusion.passive.acquisition.fans.\
StraightLineFans`, :class:`~fusion.passive.acquisition.fans.ConstantRateFans` or a subclass of
        :class:`~fusion.passive.acquisition.fans.FanStrategy`) instead of the options ``trace``,
        ``sampling``, ``refine``, ``refine_span_beams``, ``max_rate_deg_per_min``,
        ``rate_step_deg_per_min``, ``max_slope``, ``slope_step`` and ``rate_at``, which must then
        be left at their defaults. Default None: built from those options.
    freq_tolerance_bins : int
        The operator's click may be this many bins off the line (default 1): the IBW is also
        tried shifted by 1 .. `freq_tolerance_bins` bins either way, and the one whose best line
        has the largest IBW SNR is kept (0: the clicked IBW alone, as in the method).

    Notes
    -----
    Choices where the method text is silent or its equations were lost:

    - click tolerance: the method lets the operator's beam be off by up to half a beamwidth
      (segment 44's anchor beams) but takes the clicked frequency as exact; an operator reading a
      gram is as likely to be a bin off as a beam off, so the IBW gets the same tolerance
      (``freq_tolerance_bins``), and the IBW with the largest SNR wins, as the best fan does;

    - normaliser: split-window median (see :func:`normalize_spectra`);
    - fans: the method's lines are straight in beam number, but the method also assumes beams
      equally spaced in cosine (eqs. 5-11), where a target at a constant bearing rate draws a
      curve; by default each fan holds the constant-bearing-rate traces through its anchor beam,
      rates ``-max_rate .. max_rate`` in steps of ``rate_step``, each read at the nearest beam as
      ``rateest`` reads its lines (segments 62-70: mean over the scans used, minimum-scan rule,
      strictly largest mean). ``trace="beam"`` keeps the straight lines, slopes
      ``-max_slope .. max_slope`` in steps of ``slope_step``;
    - the overall best trace and its SPN give the band noise level, the IBW SNR and the defaults
      exactly as in the method (segments 50-52); only when the defaults are not used is the trace
      refined to a sub-beam end position and rate by a local search of its main-lobe matched score
      (:func:`refine_trace`), since one cell per scan cannot place a trace between beams;
    - segment 54 for a trace: the bearing of its (refined) end beam (eq. 6) and its bearing rate,
      which is already in rad/s (the trace is the integral of eq. 11); for a straight line eq. 10
      is evaluated at the middle of the line by default (at constant bearing rate the chord has
      beam rate ``(N - 1) / 2 sin(theta) theta_dot`` at the *mean* bearing to within
      ``sinc(delta_theta / 2)``);
    - SNR (eq. 4, reconstructed): SNR per bin ``~ snr_ibw * nbins_ibw``, SNR in 1 Hz
      ``= SNR_bin * dfbin * 1.3`` (Hamming equivalent noise bandwidth), in dB;
    - the lag-corrected bearing is clipped to ``[0, 180]`` deg.

    Examples
    --------
    >>> from fusion.simulate.cube import simulate_cube
    >>> sc = simulate_cube(seed=3, bearing0_deg=60.0, bearing_rate_deg_per_min=30.0, snr_db=6.0)
    >>> res = Acquisition().acquire(sc.cube, beam=sc.click_beam, freq_hz=sc.click_freq)
    >>> bool(abs(res.bearing_rate_deg_per_min - 30.0) < 7.5)
    True
    """

    def __init__(
        self,
        *,
        ibw_hz: float | None = None,
        lag_s: float = 0.0,
        normalize: bool = True,
        window_bins: int = 8,
        gap_bins: int = 1,
        noise_dof: float | None = None,
        pool_scans: int | None = None,
        trace: Literal["bearing", "beam"] = "bearing",
        sampling: Literal["nearest", "linear"] = "nearest",
        refine: bool | None = None,
        refine_span_beams: float = 2.0,
        min_scans: int | None = None,
        max_rate_deg_per_min: float | None = None,
        rate_step_deg_per_min: float | None = None,
        max_slope: float | None = None,
        slope_step: float | None = None,
        rate_at: Literal["midpoint", "latest"] = "midpoint",
        min_snr_ibw: float = 1.0,
        default_snr_ibw: float = 1.0,
        exclude_beams: float | None = None,
        fans: FanStrategy | None = None,
        freq_tolerance_bins: int = 1,
    ) -> None:
        if ibw_hz is not None and (not np.isfinite(ibw_hz) or ibw_hz <= 0):
            raise ValueError(f"ibw_hz must be positive, got {ibw_hz!r}")
        if not np.isfinite(lag_s):
            raise ValueError(f"lag_s must be finite, got {lag_s!r}")
        if min_scans is not None and (int(min_scans) != min_scans or min_scans < 2):
            raise ValueError(f"min_scans must be an integer >= 2, got {min_scans!r}")
        for name, v in (("max_slope", max_slope), ("slope_step", slope_step),
                        ("max_rate_deg_per_min", max_rate_deg_per_min),
                        ("rate_step_deg_per_min", rate_step_deg_per_min),
                        ("exclude_beams", exclude_beams), ("refine_span_beams", refine_span_beams)):
            if v is not None and (not np.isfinite(v) or v <= 0):
                raise ValueError(f"{name} must be positive, got {v!r}")
        if trace not in ("bearing", "beam"):
            raise ValueError(f"trace must be 'bearing' or 'beam', got {trace!r}")
        if sampling not in ("nearest", "linear"):
            raise ValueError(f"sampling must be 'nearest' or 'linear', got {sampling!r}")
        if trace == "beam":
            if refine:
                raise ValueError("refine applies to trace='bearing' (the straight lines are literal)")
            for name, v in (("max_rate_deg_per_min", max_rate_deg_per_min),
                            ("rate_step_deg_per_min", rate_step_deg_per_min)):
                if v is not None:
                    raise ValueError(f"{name} applies to trace='bearing'; use max_slope/slope_step")
        else:
            for name, v in (("max_slope", max_slope), ("slope_step", slope_step)):
                if v is not None:
                    raise ValueError(
                        f"{name} applies to trace='beam'; use max_rate_deg_per_min/"
                        "rate_step_deg_per_min"
                    )
        if rate_at not in ("midpoint", "latest"):
            raise ValueError(f"rate_at must be 'midpoint' or 'latest', got {rate_at!r}")
        for name, v in (("min_snr_ibw", min_snr_ibw), ("default_snr_ibw", default_snr_ibw)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive, got {v!r}")
        if noise_dof is not None and (not np.isfinite(noise_dof) or noise_dof <= 0):
            raise ValueError(f"noise_dof must be positive, got {noise_dof!r}")
        if (isinstance(freq_tolerance_bins, bool) or int(freq_tolerance_bins) != freq_tolerance_bins
                or freq_tolerance_bins < 0):
            raise ValueError(f"freq_tolerance_bins must be an integer >= 0, got "
                             f"{freq_tolerance_bins!r}")
        if pool_scans is not None and (int(pool_scans) != pool_scans or pool_scans < 1):
            raise ValueError(f"pool_scans must be a positive integer, got {pool_scans!r}")
        self.ibw_hz = ibw_hz
        self.lag_s = float(lag_s)
        self.normalize = bool(normalize)
        self.window_bins = int(window_bins)
        self.gap_bins = int(gap_bins)
        self.noise_dof = None if noise_dof is None else float(noise_dof)
        self.freq_tolerance_bins = int(freq_tolerance_bins)
        self.pool_scans = pool_scans
        self.trace = trace
        self.sampling = sampling
        self.refine = (trace == "bearing") if refine is None else bool(refine)
        self.refine_span_beams = float(refine_span_beams)
        self.min_scans = min_scans
        self.max_rate_deg_per_min = max_rate_deg_per_min
        self.rate_step_deg_per_min = rate_step_deg_per_min
        self.max_slope = max_slope
        self.slope_step = slope_step
        self.rate_at = rate_at
        self.min_snr_ibw = float(min_snr_ibw)
        self.default_snr_ibw = float(default_snr_ibw)
        self.exclude_beams = exclude_beams
        if fans is not None:
            options = {"trace": (trace, "bearing"), "sampling": (sampling, "nearest"),
                       "refine": (refine, None), "refine_span_beams": (refine_span_beams, 2.0),
                       "max_rate_deg_per_min": (max_rate_deg_per_min, None),
                       "rate_step_deg_per_min": (rate_step_deg_per_min, None),
                       "max_slope": (max_slope, None), "slope_step": (slope_step, None),
                       "rate_at": (rate_at, "midpoint")}
            given = sorted(k for k, (v, default) in options.items() if v != default)
            if given:
                raise ValueError(f"give either fans or the options {', '.join(given)}")
            if not isinstance(fans, FanStrategy):
                raise ValueError(f"fans must be a FanStrategy, got {type(fans).__name__}")
            self.fans = fans
        elif trace == "beam":
            self.fans = StraightLineFans(max_slope=max_slope, slope_step=slope_step,
                                         rate_at=rate_at)
        else:
            self.fans = ConstantRateFans(
                max_rate_deg_per_min=max_rate_deg_per_min,
                rate_step_deg_per_min=rate_step_deg_per_min, sampling=sampling,
                refine=self.refine, refine_span_beams=refine_span_beams)


    # ----------------------------------------------------------------------------------------
    def _check(self, cube: Cube, beam: int, freq_hz: float) -> float:
        if not isinstance(cube, Cube):
            raise ValueError(f"cube must be a fusion.io.Cube, got {type(cube).__name__}")
        power = np.asarray(cube.power)
        if power.ndim != 3:
            raise ValueError(f"cube power must have shape (scans, beams, bins), got {power.shape}")
        if cube.n_bins < 2:
            raise ValueError("the cube needs at least 2 frequency bins (bin spacing unknown)")
        if isinstance(beam, bool) or not float(beam).is_integer():
            raise ValueError(f"beam must be an integer beam index, got {beam!r}")
        if not 0 <= int(beam) < cube.n_beams:
            raise ValueError(f"beam {beam} is outside the cube's beams 0..{cube.n_beams - 1}")
        df = float(np.median(np.diff(cube.freqs)))
        lo, hi = cube.freqs[0] - 0.5 * df, cube.freqs[-1] + 0.5 * df
        if not np.isfinite(freq_hz) or not lo <= freq_hz <= hi:
            raise ValueError(
                f"frequency {freq_hz!r} Hz is outside the cube's band {lo:.3f}..{hi:.3f} Hz"
            )
        return df

    def _candidate_bands(self, freqs: NDArray[np.float64], freq_hz: float) -> list[NDArray[np.intp]]:
        """The IBW around the click and its copies shifted by 1 .. freq_tolerance_bins bins
        either way (those that fit in the cube), the clicked one first."""
        band = ibw_bins(freqs, freq_hz, self.ibw_hz)
        out = [band]
        for k in range(1, self.freq_tolerance_bins + 1):
            for shift in (-k, k):
                moved = band + shift
                if moved.min() >= 0 and moved.max() < freqs.size:
                    out.append(moved)
        return out

    def _spectra(self, cube: Cube, bins: NDArray[np.intp], clicked_bin: int) -> _BandView:
        """Normalised power of `bins` (segment 22), indexable by a band of bin indices."""
        n_scans = cube.power.shape[0]
        if self.normalize:
            dof = self.noise_dof
            if dof is None:
                near = np.arange(clicked_bin - self.freq_tolerance_bins - self.gap_bins - 1,
                                 clicked_bin + self.freq_tolerance_bins + self.gap_bins + 2)
                try:
                    dof = estimate_noise_dof(cube.power, exclude_bins=near)
                except ValueError as e:  # too small a cube to tell: one periodogram look
                    logger.info("noise degrees of freedom not estimated (%s): 2 assumed", e)
                    dof = 2.0
            out = normalize_spectra(cube.power, window_bins=self.window_bins,
                                    gap_bins=self.gap_bins, noise_dof=dof,
                                    pool_scans=(None if self.pool_scans is None
                                                else min(self.pool_scans, n_scans)),
                                    bins=bins)
        else:
            out = cube.power[:, :, bins]
            if not np.all(np.isfinite(out)):
                raise ValueError("cube power contains NaN or infinite values")
        return _BandView(out, bins)

    def _search(self, btr: NDArray[np.float64], anchors: NDArray[np.int64], tol: int,
                lobe_beams: float, min_scans: int,
                scan_period: float) -> tuple[float, float, BestLine | None]:
        """Segments 46-52 on one IBW BTR: IBW SNR, band noise level and the best line."""
        n_scans, n_beams = btr.shape
        btr_rev = btr[::-1]
        best_line = self.fans.search(btr_rev, anchors, min_scans=min_scans,
                                     scan_period=scan_period)
        if best_line is None:
            return float("nan"), float("nan"), None
        excl = (float(max(tol, int(math.ceil(lobe_beams)))) if self.exclude_beams is None
                else self.exclude_beams)
        # the trace over every scan, also beyond where it leaves the BTR
        track = self.fans.extend(best_line, n_scans=n_scans, n_beams=n_beams,
                                 scan_period=scan_period)
        noise = band_noise_level(btr_rev, best_line.anchor_beam, exclude_beams=excl, track=track)
        if noise <= 0:
            raise ValueError("band noise level is zero: the IBW holds no noise power")
        return (best_line.signal_plus_noise - noise) / noise, noise, best_line

    def acquire(self, cube: Cube, *, beam: int, freq_hz: float) -> AcquisitionResult:
        """Acquire the target clicked at (`beam`, `freq_hz`) on the latest scan of `cube`.

        Parameters
        ----------
        cube : fusion.io.Cube
            Beam spectra, power shape (n_scans, n_beams, n_bins), scans in time order (the last is
            the latest update), beams equally spaced in cosine from forward endfire.
        beam : int
            Clicked beam (the method's ``ibeamclick``).
        freq_hz : float
            Clicked frequency, Hz (the method's ``freqclick``).

        Returns
        -------
        AcquisitionResult

        Raises
        ------
        ValueError
            Not a cube, a beam or frequency outside the cube, NaN power, too few bins for the
            normaliser or beams for the noise level.
        """
        df = self._check(cube, beam, freq_hz)
        beam = int(beam)
        n_scans, n_beams, _ = cube.power.shape
        scan_period = float(cube.scan_period)

        # segments 40-44: beamwidth, beam tolerance, anchors
        clicked_bin = int(np.argmin(np.abs(cube.freqs - freq_hz)))
        wavelength = cube.sound_speed / float(cube.freqs[clicked_bin])
        brg_click = float(bearing_from_beam(beam, n_beams))
        bw_deg = float(beamwidth_deg(math.degrees(brg_click), wavelength=wavelength,
                                     aperture=cube.aperture))
        tol = beam_tolerance(wavelength, cube.aperture, n_beams)
        anchors = np.arange(max(0, beam - tol), min(n_beams - 1, beam + tol) + 1)
        min_scans = n_scans if self.min_scans is None else min(int(self.min_scans), n_scans)
        lobe_beams = wavelength / cube.aperture * (n_beams - 1) / 2.0  # first null, beams

        # segments 26-28 for every candidate IBW around the click (the clicked one and those
        # shifted by up to freq_tolerance_bins), then segments 46-52 on each; the candidate
        # whose best line has the largest IBW SNR is kept.
        bands = self._candidate_bands(cube.freqs, freq_hz)
        spectra = self._spectra(cube, np.unique(np.concatenate(bands)), clicked_bin)
        tried = []
        for band in bands:
            btr = ibw_btr(spectra[band])  # (scans, beams), chronological
            tried.append((band, btr, *self._search(btr, anchors, tol, lobe_beams, min_scans,
                                                   scan_period)))
        snrs = np.array([t[2] for t in tried])
        pick = int(np.nanargmax(snrs)) if np.isfinite(snrs).any() else 0
        band, btr, snr_ibw, noise, best_line = tried[pick]
        btr_rev = btr[::-1]  # row 0 = latest update, as in the method's btr[iscan][ibeam]

        common = {"snr_ibw": snr_ibw, "btr": btr, "band_noise_level": noise,
                  "beamwidth_deg": bw_deg, "beam_tolerance": tol,
                  "anchor_beams": tuple(int(b) for b in anchors),
                  "ibw_bins": tuple(int(b) for b in band)}
        nbins_ibw = int(band.size)
        if best_line is None or not snr_ibw > self.min_snr_ibw:
            # defaults (segment 52): rate 0, clicked beam's bearing, default SNR through eq. 4
            logger.info("IBW SNR %.3g <= %.3g: default estimates", snr_ibw, self.min_snr_ibw)
            return AcquisitionResult(
                bearing_deg=math.degrees(brg_click), bearing_rate_deg_per_min=0.0,
                snr_db=snr_1hz_db(self.default_snr_ibw, nbins_ibw, df), default_used=True,
                bearing_uncorrected_deg=math.degrees(brg_click), best_line=best_line, **common)

        # refinement of the overall best line (the SPN and SNR stay the fan search's)
        best_line = self.fans.refine_line(best_line, btr_rev, min_scans=min_scans,
                                          scan_period=scan_period, lobe_beams=lobe_beams,
                                          noise_level=noise)

        # segment 54: beam -> bearing (eq. 6), bearing rate, lag correction
        rate_rad_s = self.fans.bearing_rate(best_line, n_beams=n_beams, scan_period=scan_period)
        brg_uncorrected = float(bearing_from_beam(best_line.end_beam, n_beams))
        brg = min(max(brg_uncorrected + rate_rad_s * self.lag_s, 0.0), math.pi)
        return AcquisitionResult(
            bearing_deg=math.degrees(brg),
            bearing_rate_deg_per_min=math.degrees(rate_rad_s) * 60.0,
            snr_db=snr_1hz_db(snr_ibw, nbins_ibw, df),
            default_used=False,
            bearing_uncorrected_deg=math.degrees(brg_uncorrected),
            best_line=best_line,
            **common,
        )


def acquire(cube: Cube, *, beam: int, freq_hz: float, **options: object) -> AcquisitionResult:
    """Function form of :class:`Acquisition`: ``Acquisition(**options).acquire(cube, ...)``.

    Parameters
    ----------
    cube : fusion.io.Cube
        Beam spectra, shape (n_scans, n_beams, n_bins), the last scan the latest.
    beam : int
        Clicked beam.
    freq_hz : float
        Clicked frequency, Hz.
    **options
        Keyword options of :class:`Acquisition`.

    Returns
    -------
    AcquisitionResult
    """
    return Acquisition(**options).acquire(cube, beam=beam, freq_hz=freq_hz)  # type: ignore[arg-type]
