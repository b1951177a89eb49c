"""What the click front end returns: a window's candidate TDOAs and the window itself.

:class:`WindowTdoa` and :class:`ClickWindow` are the results of
:class:`fusion.pipelines.clicks.ClickFrontEnd` and of its streaming part
(:mod:`fusion.pipelines.clicks.stream`): data of the click front end, kept with its other types
below the pipelines so that neither pipeline module imports the other's. Also importable from
:mod:`fusion.pipelines.clicks`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from fusion.clicks.associate import TdoaClicks
from fusion.clicks.types import ChannelClicks
from fusion.types import frozen_array

__all__ = ["ClickWindow", "WindowTdoa"]


@dataclass(frozen=True)
class WindowTdoa:
    """One candidate TDOA of a processing window and everything measured about it.

    Attributes
    ----------
    pair : tuple of int
        Sensor indices ``(i, j)``, ``i < j``.
    tau_s : float
        ``t_i - t_j`` at the window centre, s: the refined value where the waveforms allowed a
        refinement, else the SCM peak.
    tau_coarse_s : float
        The SCM correlation peak (eq. 6), s.
    sigma_s : float
        Standard deviation of `tau_s`, s (refined: from the data; coarse: the SCM pulse width).
    crb_s : float
        Cramér-Rao bound of the refined TDOA at the measured SNR, s (NaN when not refined).
    snr_db : float
        Click SNR the refinement measured (the weaker sensor's), dB (NaN when not refined).
    rate : float
        Drift of the delay through the window, s/s (the refinement's fit; 0 when not refined).
    scm_peak : float
        Correlation value at the peak (about the number of matching clicks, eq. 4-6).
    n_clicks : int
        Source clicks the SCM2 matched.
    features : ndarray, shape (4,)
        ``[specmax, mu1, mu2', mu3']`` of the SCM2 (eq. 10).
    llr : float
        Validation log-likelihood ratio (eq. 11).
    passes : bool
        ``llr`` at or above the validator's threshold.
    confirmed : bool
        Linked across time to the previous or the next window (eq. 12, [0041]).
    consistent : bool
        Passes the triangle closure check (True when no triangle tested it).
    click_times_s : ndarray, shape (k,)
        Source click times at sensor ``i``, s from the start of the audio: the clicks the
        refinement matched along the delay's drift through the window where it succeeded,
        else the SCM2's (used by the association, eq. 12-13).
    t_s : float
        Arrival time at sensor ``i`` at which `tau_s` holds, s from the start of the audio (the
        window centre; ``tau_s + rate (t - t_s)`` follows the delay through the window).
    train_z : float
        For a TDOA found by integrating a click train (:mod:`fusion.pipelines.clicks.
        train_tdoas`): the excess of its sum over the sum's noise, robust standard deviations;
        NaN for the click-map TDOAs.
    """

    pair: tuple[int, int]
    tau_s: float
    tau_coarse_s: float
    sigma_s: float
    crb_s: float
    snr_db: float
    rate: float
    scm_peak: float
    n_clicks: int
    features: NDArray[np.float64]
    llr: float
    passes: bool
    confirmed: bool = False
    consistent: bool = True
    click_times_s: NDArray[np.float64] = field(default_factory=lambda: frozen_array([]))
    t_s: float = math.nan
    train_z: float = math.nan

    def __post_init__(self) -> None:
        object.__setattr__(self, "features", frozen_array(self.features))
        object.__setattr__(self, "click_times_s", frozen_array(self.click_times_s))

    @property
    def valid(self) -> bool:
        """Passes validation and is confirmed across time."""
        return bool(self.passes and self.confirmed)

    def as_clicks(self) -> TdoaClicks:
        """The TDOA with its click times, as the association stage takes it."""
        return TdoaClicks(self.pair, self.tau_s, self.click_times_s, self.sigma_s, self.rate)


@dataclass(frozen=True)
class ClickWindow:
    """The front end's result for one processing window.

    Attributes
    ----------
    t_start, t_end : float
        Window, s from the start of the audio.
    clicks : tuple of ChannelClicks
        Clicks detected on each channel within the window.
    tdoas : tuple of WindowTdoa
        Every candidate TDOA (valid or not).
    alpha : ndarray, shape (M, M)
        Cross-pair association (eq. 13) among the `tdoas` that pass validation (0 between
        TDOAs not sharing exactly one sensor, and for TDOAs that failed validation).
    links_previous : tuple of (int, int)
        ``(index in the previous window, index here)`` of the time association.
    """

    t_start: float
    t_end: float
    clicks: tuple[ChannelClicks, ...]
    tdoas: tuple[WindowTdoa, ...]
    alpha: NDArray[np.float64]
    links_previous: tuple[tuple[int, int], ...] = ()

    @property
    def valid_tdoas(self) -> tuple[WindowTdoa, ...]:
        """The TDOAs that pass validation and are confirmed."""
        return tuple(d for d in self.tdoas if d.valid)
