"""Track quality indicator (TQI) with hysteresis, vectorised over many trackers.

Implements *Track Quality Indicator with Hysteresis* (W. R. Lane, US patent application
10/241389), flow steps 100-132 of its FIGS. 2A-2C, for any number of narrowband trackers at once:
every update is a handful of numpy operations on arrays of shape ``(n_tracks,)``.

Per update ``k`` and tracker (method text, "summed log likelihood ratios")::

    a_i(k)   = Ahat(k) / O_i,  p_i = C_i / O_i                          i = 0, 1
    LLR_0(k) = p_0 [a_0(k) - p_0 / 2]
    LLR_1(k) = p_1 [a_1(k) - 0.85 p_1]
    SLLR_i(k) = max(min(SLLR_i(k-1) + LLR_i(k), TM_i), TL_i)

``LLR_0`` is printed with ``p_i`` in front; the project's design notes read it as ``p_0`` (the only
reading that makes it the Gaussian log likelihood ratio of mean ``C_0`` against mean 0), and so
does this module. The hysteresis flow (steps 102-132) then turns ``SLLR_0``, ``SLLR_1`` and the
smoothed error residual into one of four states: :class:`TrackQuality`.

Decisions where the method text is silent (all exposed as keyword parameters):

* **Amplitude estimate.** The tracker reports ``A(k)``, the power in its cell on the normalised
  scale (noise alone has mean 1). The likelihood ratios compare "signal present at the design
  SNR" against "no signal" with a Gaussian of equal spread, which only makes sense for an amplitude
  whose mean is 0 under noise; the amplitude estimate is therefore the power above the noise mean,
  ``Ahat = A - noise_mean``, and ``C_i``, ``O_i`` are the mean and standard deviation of ``Ahat``
  at the design SNRs (:func:`design_statistics`, from the tracker's cell statistics
  :func:`fusion.passive.tracker.cell_power_statistics`).
* **Clamps** ``TL_i``, ``TM_i`` (not given in the text). ``SLLR_1``: one hysteresis width beyond
  the thresholds it is compared with, ``[TS - 2 SH, TS + 2 SH]``. ``SLLR_0``: floor ``TL - LH``,
  ceiling ``TU + LH + 0.25`` (:data:`SLLR0_CEILING_MARGIN`). The ceiling is the evidence a loss
  must undo before ``lost``: noise alone takes ``p_0^2 / 2`` per update off ``SLLR_0``, so the
  delay from a loss to ``lost`` is about ``(TM_0 - TL) / (p_0^2 / 2)`` updates (17 for single-look
  cells at the default design SNR, against 21 with the former ceiling ``TU + 2 LH``), while a
  lower ceiling leaves the track more easily near the thresholds. ``TU + LH`` is the least that
  still lets a track leave ``uncertain``; the margin above it was chosen on the trade-off of loss
  delay against state changes measured on varied scenarios (``benchmarks/bench_tqi.py
  --tradeoff``). The SLLRs start at 0 clipped into their clamps.
* **Smoothed residual.** ``ES`` is smoothed recursively (first-order, gain ``residual_smoothing``);
  ``SRESVAR`` is the standard deviation of that smoothed residual, ``sigma_r sqrt(b / (2 - b))``,
  with ``sigma_r^2`` the recursively smoothed squared deviation of the raw residual from ``ES``.
* **Error detector gain** ``KE = |SNR| / (1.744 + |SNR|)`` (method text, error detector model) with
  ``SNR`` the recursively smoothed amplitude estimate ``Ahat`` (gain ``snr_smoothing``).
* **ERR_max.** The printed equation is garbled; the design notes' reading is
  ``ERR_max = (n KE / (2 Omega) + T_err SRESVAR) Omega / (n KE)``, a threshold in units of
  ``n KE / Omega`` of the residual. The residual is compared in the same units,
  ``|ES| Omega / (n KE) > ERR_max``, which (multiplying through by ``n KE / Omega > 0``) is
  ``|ES| > n KE / (2 Omega) + T_err SRESVAR``: half the error detector's linear range plus
  ``T_err`` standard deviations of the smoothed residual. That last form is what is computed, in
  degrees, so it stays finite when ``KE`` is 0; :attr:`TQIHistory.err_max_deg` reports it.
  ``Omega`` is in 1/deg: ``n / Omega`` is the linear range of the error detector, about one
  beamwidth (:func:`omega_for_beamwidth`).
* **Start state.** Before the first update there is no ``TQI(k-1)``; it is treated like the
  flow's "neither" branches (step 102 no, step 108 no, step 116 no, step 124 no): lost if
  ``SLLR_0 <= TL``, else uncertain if the residual is too large, else low SNR or strong by
  ``SLLR_1`` against ``TS + SH``.

Examples
--------
>>> import numpy as np
>>> from fusion.passive.quality import TrackQuality
>>> tqi = TrackQualityIndicator(snr0_db=3.0, snr1_db=10.0)
>>> rng = np.random.default_rng(0)
>>> amp = 1.0 + 20.0 * np.ones((30, 4))          # 13 dB above the noise in every cell
>>> hist = tqi.run(amp, 0.1 * rng.standard_normal((30, 4)))
>>> [TrackQuality(s).label for s in hist.state[-1]]
['strong', 'strong', 'strong', 'strong']
"""

from __future__ import annotations

import logging

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.passive.quality.flow import design_statistics, tqi_transition
from fusion.passive.quality.types import START, TQIHistory, TQIMemory

__all__ = ["SLLR0_CEILING_MARGIN", "TrackQualityIndicator"]

logger = logging.getLogger(__name__)

#: Default ceiling of ``SLLR_0`` above ``TU + LH`` (see the module notes on clamps).
SLLR0_CEILING_MARGIN: float = 0.25


class TrackQualityIndicator:
    """TQI with hysteresis for many narrowband trackers at once.

    Parameters
    ----------
    snr0_db : float, optional
        Design SNR ``SNR_0`` of the tracker threshold, per cell, dB.
    snr1_db : float, optional
        Design SNR ``SNR_1`` of a strong track, per cell, dB.
    n_looks : int, optional
        Independent looks averaged in one cell of the spectra (sets ``C_i``, ``O_i``).
    noise_mean : float, optional
        Mean noise power of the normalised spectra.
    tl, tu, ts : float, optional
        Lost, uncertain and strong thresholds (method defaults -3.5, 1.75, 7.0).
    lh, sh : float, optional
        Low-SNR and strong-SNR hysteresis constants (method defaults 1.5, 2.0).
    hysteresis : bool, optional
        False gives the comparison variant with single thresholds (``LH = SH = 0`` in the flow);
        the SLLRs, clamps and residual test are unchanged.
    sllr0_limits, sllr1_limits : (float, float), optional
        Clamps ``(TL_i, TM_i)``; default ``(TL - LH, TU + LH + 0.25)`` and
        ``(TS - 2 SH, TS + 2 SH)`` (the ``SLLR_0`` ceiling sets the delay from a loss to
        ``lost``; module notes).
    omega : float, optional
        Effective angular centre frequency ``Omega`` of the error detector, 1/deg.
    n : float, optional
        The method's constant ``n`` (0.5).
    t_err : float, optional
        The method's constant ``T_err`` (3.0).
    residual_smoothing : float, optional
        Gain ``b`` in (0, 1] of the recursive residual smoother ``ES(k) = ES(k-1) + b (r - ES(k-1))``.
    snr_smoothing : float, optional
        Gain in (0, 1] of the recursive SNR estimate behind ``KE``.
    residual_std0_deg : float, optional
        Raw residual standard deviation assumed before the first update, deg.

    Attributes
    ----------
    design_mean : ndarray, shape (2,)
        ``(C_0, C_1)``: mean amplitude estimate at ``SNR_0`` and ``SNR_1``.
    design_std : ndarray, shape (2,)
        ``(O_0, O_1)``: its standard deviations.
    memory : TQIMemory or None
        Streaming state after the last :meth:`update` (None before the first one).

    Notes
    -----
    Implements flow steps 100-132 of *Track Quality Indicator with Hysteresis*; see the module
    docstring for the equations and for the choices where the text is silent.
    """

    def __init__(
        self,
        *,
        snr0_db: float = 3.0,
        snr1_db: float = 10.0,
        n_looks: int = 1,
        noise_mean: float = 1.0,
        tl: float = -3.5,
        tu: float = 1.75,
        ts: float = 7.0,
        lh: float = 1.5,
        sh: float = 2.0,
        hysteresis: bool = True,
        sllr0_limits: tuple[float, float] | None = None,
        sllr1_limits: tuple[float, float] | None = None,
        omega: float = 0.25,
        n: float = 0.5,
        t_err: float = 3.0,
        residual_smoothing: float = 0.1,
        snr_smoothing: float = 0.1,
        residual_std0_deg: float = 1.0,
    ) -> None:
        for name, v in (("snr0_db", snr0_db), ("snr1_db", snr1_db), ("tl", tl), ("tu", tu),
                        ("ts", ts), ("lh", lh), ("sh", sh)):
            if not np.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v!r}")
        if snr1_db <= snr0_db:
            raise ValueError(f"snr1_db ({snr1_db}) must exceed snr0_db ({snr0_db})")
        if lh < 0 or sh < 0:
            raise ValueError(f"hysteresis constants must be >= 0, got lh={lh}, sh={sh}")
        if not tl < tu:
            raise ValueError(f"lost threshold tl ({tl}) must be below uncertain threshold tu ({tu})")
        for name, v in (("omega", omega), ("n", n), ("noise_mean", noise_mean),
                        ("residual_std0_deg", residual_std0_deg)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive, got {v!r}")
        if not np.isfinite(t_err) or t_err < 0:
            raise ValueError(f"t_err must be >= 0, got {t_err!r}")
        for name, v in (("residual_smoothing", residual_smoothing),
                        ("snr_smoothing", snr_smoothing)):
            if not (0.0 < v <= 1.0):
                raise ValueError(f"{name} must lie in (0, 1], got {v!r}")
        self.snr_db = np.array([snr0_db, snr1_db], dtype=float)
        self.n_looks = int(n_looks)
        self.noise_mean = float(noise_mean)
        # C_i, O_i from the tracker's amplitude statistics at the design SNRs
        self.design_mean, self.design_std = design_statistics(
            self.snr_db, n_looks=n_looks, noise_mean=noise_mean
        )
        self.tl, self.tu, self.ts, self.lh, self.sh = map(float, (tl, tu, ts, lh, sh))
        self.hysteresis = bool(hysteresis)
        lim0 = ((tl - lh, tu + lh + SLLR0_CEILING_MARGIN) if sllr0_limits is None
                else tuple(map(float, sllr0_limits)))
        lim1 = (ts - 2 * sh, ts + 2 * sh) if sllr1_limits is None else tuple(map(float, sllr1_limits))
        for name, (lo, hi) in (("sllr0_limits", lim0), ("sllr1_limits", lim1)):
            if not (np.isfinite(lo) and np.isfinite(hi) and lo < hi):
                raise ValueError(f"{name} must be finite with min < max, got {(lo, hi)}")
        if lim0[0] > tl:
            logger.warning("SLLR_0 floor %g is above TL %g: the lost state is unreachable", lim0[0], tl)
        self.sllr0_limits, self.sllr1_limits = lim0, lim1
        self.omega, self.n, self.t_err = float(omega), float(n), float(t_err)
        self.residual_smoothing = float(residual_smoothing)
        self.snr_smoothing = float(snr_smoothing)
        self.residual_std0_deg = float(residual_std0_deg)
        self.memory: TQIMemory | None = None

    # ------------------------------------------------------------------------------------
    @property
    def p(self) -> NDArray[np.float64]:
        """Normalised theoretical amplitude means ``p_i = C_i / O_i``, shape (2,)."""
        return self.design_mean / self.design_std

    def initial_memory(self, n_tracks: int) -> TQIMemory:
        """Memory of `n_tracks` trackers before their first update."""
        if int(n_tracks) != n_tracks or n_tracks < 1:
            raise ValueError(f"n_tracks must be a positive integer, got {n_tracks!r}")
        z = np.zeros(int(n_tracks))
        return TQIMemory(
            state=np.full(int(n_tracks), START, dtype=np.int8),
            sllr0=np.clip(z, *self.sllr0_limits),
            sllr1=np.clip(z, *self.sllr1_limits),
            residual_deg=z.copy(),
            residual_var=np.full(int(n_tracks), self.residual_std0_deg**2),
            snr=z.copy(),
            err_max_deg=np.full(int(n_tracks), np.nan),
        )

    def reset(self, n_tracks: int) -> None:
        """Start streaming afresh for `n_tracks` trackers."""
        self.memory = self.initial_memory(n_tracks)

    def step(
        self,
        memory: TQIMemory,
        amplitude: ArrayLike,
        residual_deg: ArrayLike,
        *,
        active: ArrayLike | None = None,
    ) -> TQIMemory:
        """Pure update: the memory after one update of every (active) tracker.

        Parameters
        ----------
        memory : TQIMemory
            Memory before the update (not modified).
        amplitude : array_like, shape (n,)
            Tracker cell power ``A(k)``, linear, normalised (noise mean `noise_mean`).
        residual_deg : array_like, shape (n,)
            Tracker error residual, deg.
        active : array_like of bool, shape (n,), optional
            Trackers updated at this step; the others keep their memory (their amplitude and
            residual may then be NaN).

        Returns
        -------
        TQIMemory
        """
        n = memory.n_tracks
        a = np.asarray(amplitude, dtype=float)
        r = np.asarray(residual_deg, dtype=float)
        if a.shape != (n,) or r.shape != (n,):
            raise ValueError(
                f"amplitude and residual must have shape ({n},), got {a.shape} and {r.shape}"
            )
        act = np.ones(n, dtype=bool) if active is None else np.asarray(active, dtype=bool)
        if act.shape != (n,):
            raise ValueError(f"active must have shape ({n},), got {act.shape}")
        if not (np.all(np.isfinite(a[act])) and np.all(np.isfinite(r[act]))):
            raise ValueError("amplitude and residual must be finite for every active tracker")
        if np.any(a[act] < 0):
            raise ValueError("amplitude must be >= 0 (linear power)")
        a = np.where(act, a, self.noise_mean)
        r = np.where(act, r, 0.0)

        # amplitude estimate above the noise mean, normalised: a_i(k) = Ahat(k) / O_i
        ahat = a - self.noise_mean
        p0, p1 = self.p
        o0, o1 = self.design_std
        llr0 = p0 * (ahat / o0 - 0.5 * p0)  # LLR_0(k) = p_0 [a_0(k) - p_0 / 2]
        llr1 = p1 * (ahat / o1 - 0.85 * p1)  # LLR_1(k) = p_1 [a_1(k) - 0.85 p_1]
        # SLLR_i(k) = max(min(SLLR_i(k-1) + LLR_i(k), TM_i), TL_i)
        sllr0 = np.clip(memory.sllr0 + llr0, *self.sllr0_limits)
        sllr1 = np.clip(memory.sllr1 + llr1, *self.sllr1_limits)

        # error detector gain KE = |SNR| / (1.744 + |SNR|) from the smoothed SNR estimate
        snr = memory.snr + self.snr_smoothing * (ahat - memory.snr)
        ke = np.abs(snr) / (1.744 + np.abs(snr))
        # recursive smoothed residual ES and its standard deviation SRESVAR
        b = self.residual_smoothing
        dev = r - memory.residual_deg
        es = memory.residual_deg + b * dev
        var = memory.residual_var + b * (dev * dev - memory.residual_var)
        sresvar = np.sqrt(var * b / (2.0 - b))
        # ERR_max, multiplied through by n KE / Omega: |ES| > n KE / (2 Omega) + T_err SRESVAR
        err_max = self.n * ke / (2.0 * self.omega) + self.t_err * sresvar
        high = np.abs(es) > err_max

        lh, sh = (self.lh, self.sh) if self.hysteresis else (0.0, 0.0)
        state = tqi_transition(
            memory.state, sllr0, sllr1, high, tl=self.tl, tu=self.tu, ts=self.ts, lh=lh, sh=sh
        )
        return TQIMemory(
            state=np.where(act, state, memory.state).astype(np.int8),
            sllr0=np.where(act, sllr0, memory.sllr0),
            sllr1=np.where(act, sllr1, memory.sllr1),
            residual_deg=np.where(act, es, memory.residual_deg),
            residual_var=np.where(act, var, memory.residual_var),
            snr=np.where(act, snr, memory.snr),
            err_max_deg=np.where(act, err_max, memory.err_max_deg),
        )

    def update(
        self, amplitude: ArrayLike, residual_deg: ArrayLike, *, active: ArrayLike | None = None
    ) -> NDArray[np.int8]:
        """Streaming update of every tracker: the new TQI states.

        Parameters
        ----------
        amplitude : array_like, shape (n,)
            Tracker cell power ``A(k)``, linear, normalised.
        residual_deg : array_like, shape (n,)
            Tracker error residual, deg.
        active : array_like of bool, shape (n,), optional
            Trackers updated now (default all).

        Returns
        -------
        ndarray of int8, shape (n,)
            :class:`TrackQuality` codes after the update.
        """
        a = np.asarray(amplitude, dtype=float)
        if self.memory is None:
            if a.ndim != 1:
                raise ValueError(f"amplitude must be 1-D (one value per tracker), got {a.shape}")
            self.reset(a.shape[0])
        self.memory = self.step(self.memory, a, residual_deg, active=active)
        return self.memory.state

    def run(
        self, amplitude: ArrayLike, residual_deg: ArrayLike, *, valid: ArrayLike | None = None
    ) -> TQIHistory:
        """Batch TQI of whole sequences, from a fresh start (the streaming memory is untouched).

        Parameters
        ----------
        amplitude : array_like, shape (n_updates, n_tracks) or (n_updates,)
            Tracker cell powers, linear, normalised; a 1-D input is one tracker.
        residual_deg : array_like, same shape
            Tracker error residuals, deg.
        valid : array_like of bool, same shape, optional
            Which entries are updates (ragged sequences padded with NaN); default all.

        Returns
        -------
        TQIHistory
            Arrays of shape (n_updates, n_tracks).
        """
        a = np.asarray(amplitude, dtype=float)
        r = np.asarray(residual_deg, dtype=float)
        if a.ndim == 1:
            a, r = a[:, None], r.reshape(-1, 1)
        if a.ndim != 2 or a.shape != r.shape:
            raise ValueError(
                f"amplitude and residual must have one shape (n_updates, n_tracks), "
                f"got {np.shape(amplitude)} and {np.shape(residual_deg)}"
            )
        if a.shape[0] == 0 or a.shape[1] == 0:
            raise ValueError(f"nothing to do: amplitude has shape {a.shape}")
        v = np.ones(a.shape, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
        if v.ndim == 1:
            v = v[:, None]
        if v.shape != a.shape:
            raise ValueError(f"valid must have shape {a.shape}, got {v.shape}")
        mem = self.initial_memory(a.shape[1])
        out = {k: np.empty(a.shape) for k in ("sllr0", "sllr1", "residual_deg", "err_max_deg")}
        state = np.empty(a.shape, dtype=np.int8)
        for k in range(a.shape[0]):
            mem = self.step(mem, a[k], r[k], active=v[k])
            state[k] = mem.state
            for name, arr in out.items():
                arr[k] = getattr(mem, name)
        return TQIHistory(state=state, **out)
