"""Per-receiver sonar accuracy estimated from the data: echoes that come back ping after ping.

The bistatic error ellipse of a detection (:func:`fusion.active.bistatic.bistatic_covariance`)
needs the accuracy of the range sum and of the receiver bearing. They differ from receiver to
receiver and from one sea to another, and the paper ("Target tracking using fuzzy logic
association") is silent on them; handing a tracker the values a simulator drew its errors from
would hide exactly the mismatch a real system meets. :class:`NoiseEstimator` learns them from
the detections themselves.

Method
------
Every detection with source and receiver positions maps back to the quantities the receiver
measured: the range sum ``rho = |p - s| + |p - r|`` and the bearing ``theta`` from the receiver.
Bottom features echo from (nearly) the same place on many pings, so between two pings of one
receiver the differences ``(d_rho, d_theta)`` of echoes of one feature are zero-mean Gaussian
with variances ``2 sigma_rho^2`` and ``2 sigma_theta^2``, while pairs of unrelated echoes spread
evenly over any small window. Per receiver (one source-receiver geometry), the pairs of each new
ping's detections with those of the previous ``lag_pings`` pings that fall within the window
``|d_rho| <= window_range_sum_m``, ``|d_theta| <= window_bearing_deg`` are fitted by a two-part
mixture: the zero-mean Gaussian plus a uniform background, by expectation-maximisation. The
variances carry a conjugate prior worth ``prior_pairs`` pairs at the user's values
(``range_sum_sigma_m``, ``bearing_sigma_deg``), so the estimate starts at the user's setting and
moves to the data's as pairs accumulate:
``sigma^2 = (n_0 sigma_0^2 + sum_i w_i d_i^2 / 2) / (n_0 + sum_i w_i)`` with ``w_i`` the
posterior weight of pair ``i`` in the Gaussian part.

A moving target's echoes pair too, with a non-zero mean; over one ping they move less than the
window and slightly widen the estimate, over longer lags they join the background. Without
source and receiver positions (e.g. radar) nothing is estimated.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.active.types import POSITION_CLUES, Ping, receiver_groups

__all__ = ["NoiseEstimator", "ReceiverNoise", "range_sum_and_bearing"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class ReceiverNoise:
    """Estimated accuracy of one receiver.

    Attributes
    ----------
    range_sum_sigma_m : float
        Standard deviation of the bistatic range sum, m.
    bearing_sigma_deg : float
        Standard deviation of the receiver bearing, deg.
    pairs : float
        Effective number of echo pairs behind the estimate (sum of the Gaussian part's weights).
    """

    range_sum_sigma_m: float
    bearing_sigma_deg: float
    pairs: float


def range_sum_and_bearing(
    xy: NDArray[np.float64], source: NDArray[np.float64], receiver: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Range sum (m) and compass bearing from the receiver (rad) of echo positions.

    Parameters
    ----------
    xy, source, receiver : ndarray, shape (n, 2) or (2,)
        Echo, source and receiver positions, m.

    Returns
    -------
    rho, theta : ndarray, shape (n,)
        ``|p - s| + |p - r|`` and ``atan2(p_x - r_x, p_y - r_y)`` (clockwise from north).
    """
    p = np.asarray(xy, dtype=float).reshape(-1, 2)
    s = np.broadcast_to(np.asarray(source, dtype=float), p.shape)
    r = np.broadcast_to(np.asarray(receiver, dtype=float), p.shape)
    rho = np.hypot(*(p - s).T) + np.hypot(*(p - r).T)
    theta = np.arctan2(p[:, 0] - r[:, 0], p[:, 1] - r[:, 1])
    return rho, theta


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.remainder(a + np.pi, 2.0 * np.pi) - np.pi


class NoiseEstimator:
    """Range-sum and bearing accuracy per receiver, learnt online from recurring echoes.

    Parameters
    ----------
    range_sum_sigma_m : float, optional
        Prior (user) range-sum accuracy, m (> 0, default 100).
    bearing_sigma_deg : float, optional
        Prior (user) bearing accuracy, deg (> 0, default 1.5).
    prior_pairs : float, optional
        Weight of the prior, in echo pairs (>= 0, default 20); 0 trusts the data alone once any
        pair is seen.
    lag_pings : int, optional
        Each ping's detections pair with those of this many previous pings (>= 1, default 3).
    window_range_sum_m, window_bearing_deg : float, optional
        Half-widths of the pair window in range sum (m, default 2000) and bearing (deg,
        default 8).
    max_pairs : int, optional
        Most recent pairs kept per receiver (default 5000).
    min_sigma_m, min_sigma_deg : float, optional
        Floors of the estimates (defaults 5 m and 0.1 deg).

    Notes
    -----
    :meth:`update` adds a ping; :meth:`sigmas` gives each detection of a ping the current
    estimate of its receiver (the prior for a receiver not seen yet). See the module docstring
    for the model.

    Examples
    --------
    >>> est = NoiseEstimator(range_sum_sigma_m=50.0, bearing_sigma_deg=1.0)
    >>> est.estimate((0, 0, 0, 0)).range_sum_sigma_m
    50.0
    """

    def __init__(
        self,
        *,
        range_sum_sigma_m: float = 100.0,
        bearing_sigma_deg: float = 1.5,
        prior_pairs: float = 20.0,
        lag_pings: int = 3,
        window_range_sum_m: float = 2000.0,
        window_bearing_deg: float = 8.0,
        max_pairs: int = 5000,
        min_sigma_m: float = 5.0,
        min_sigma_deg: float = 0.1,
    ) -> None:
        for name, v in (("range_sum_sigma_m", range_sum_sigma_m),
                        ("bearing_sigma_deg", bearing_sigma_deg),
                        ("window_range_sum_m", window_range_sum_m),
                        ("window_bearing_deg", window_bearing_deg),
                        ("min_sigma_m", min_sigma_m), ("min_sigma_deg", min_sigma_deg)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive, got {v!r}")
        if not np.isfinite(prior_pairs) or prior_pairs < 0:
            raise ValueError(f"prior_pairs must be >= 0, got {prior_pairs!r}")
        if int(lag_pings) != lag_pings or lag_pings < 1:
            raise ValueError(f"lag_pings must be an integer >= 1, got {lag_pings!r}")
        if int(max_pairs) != max_pairs or max_pairs < 10:
            raise ValueError(f"max_pairs must be an integer >= 10, got {max_pairs!r}")
        self.range_sum_sigma_m = float(range_sum_sigma_m)
        self.bearing_sigma_deg = float(bearing_sigma_deg)
        self.prior_pairs = float(prior_pairs)
        self.lag_pings = int(lag_pings)
        self.window_range_sum_m = float(window_range_sum_m)
        self.window_bearing_rad = math.radians(window_bearing_deg)
        self.max_pairs = int(max_pairs)
        self.min_sigma_m = float(min_sigma_m)
        self.min_sigma_rad = math.radians(min_sigma_deg)
        self.reset()

    def empty_copy(self) -> NoiseEstimator:
        """An estimator with the same options and nothing learnt."""
        return NoiseEstimator(
            range_sum_sigma_m=self.range_sum_sigma_m, bearing_sigma_deg=self.bearing_sigma_deg,
            prior_pairs=self.prior_pairs, lag_pings=self.lag_pings,
            window_range_sum_m=self.window_range_sum_m,
            window_bearing_deg=math.degrees(self.window_bearing_rad), max_pairs=self.max_pairs,
            min_sigma_m=self.min_sigma_m, min_sigma_deg=math.degrees(self.min_sigma_rad))

    def reset(self) -> None:
        """Forget everything learnt."""
        # Per geometry key (rounded src_x, src_y, rcv_x, rcv_y): recent pings' (rho, theta),
        # the pair differences kept, and the current estimate.
        self._history: dict[tuple[float, ...], deque] = {}
        self._pairs: dict[tuple[float, ...], NDArray[np.float64]] = {}
        self._estimate: dict[tuple[float, ...], ReceiverNoise] = {}
        # Per geometry: the last fit's variances and mixing weight (EM starts from them).
        self._state: dict[tuple[float, ...], tuple[float, float, float]] = {}

    def estimate(self, key: tuple[float, ...]) -> ReceiverNoise:
        """Current estimate for a geometry (``src_x, src_y, rcv_x, rcv_y`` rounded to 1 m, the
        keys of :func:`fusion.active.types.receiver_groups`); the prior for one not seen yet."""
        return self._estimate.get(tuple(key), ReceiverNoise(self.range_sum_sigma_m,
                                                            self.bearing_sigma_deg, 0.0))

    def estimates(self) -> dict[tuple[float, ...], ReceiverNoise]:
        """Current estimate of every geometry seen (a copy)."""
        return dict(self._estimate)

    @staticmethod
    def _geometry(ping: Ping) -> NDArray[np.float64] | None:
        if not all(k in ping.clues for k in POSITION_CLUES):
            return None
        geo = np.column_stack([ping.clues[k] for k in POSITION_CLUES])
        return geo if np.all(np.isfinite(geo)) else None

    def update(self, ping: Ping) -> None:
        """Add one ping's detections: pair them with the previous pings' and refit.

        Parameters
        ----------
        ping : Ping
            Detections; without ``src_x, src_y, rcv_x, rcv_y`` nothing is learnt.
        """
        geo = self._geometry(ping)
        if geo is None or ping.n == 0:
            return
        rho, theta = range_sum_and_bearing(ping.xy, geo[:, :2], geo[:, 2:])
        for key, sel in receiver_groups(ping):
            new = np.column_stack([rho[sel], theta[sel]])
            hist = self._history.setdefault(key, deque(maxlen=self.lag_pings))
            if hist:
                old = np.concatenate(list(hist))
                d_rho = new[:, None, 0] - old[None, :, 0]
                i, j = np.nonzero(np.abs(d_rho) <= self.window_range_sum_m)
                d_th = _wrap(new[i, 1] - old[j, 1])
                inside = np.abs(d_th) <= self.window_bearing_rad
                if inside.any():
                    fresh = np.column_stack([d_rho[i[inside], j[inside]], d_th[inside]])
                    kept = self._pairs.get(key)
                    both = fresh if kept is None else np.concatenate([kept, fresh])
                    self._pairs[key] = both[-self.max_pairs:]
                    self._estimate[key] = self._fit(self._pairs[key], self._state.get(key))
                    e = self._estimate[key]
                    self._state[key] = (e.range_sum_sigma_m**2,
                                        math.radians(e.bearing_sigma_deg) ** 2,
                                        e.pairs / self._pairs[key].shape[0])
            hist.append(new)

    def _fit(self, d: NDArray[np.float64],
             start: tuple[float, float, float] | None = None) -> ReceiverNoise:
        """EM fit of the zero-mean Gaussian + uniform mixture to pair differences ``d``
        (columns ``d_rho`` m, ``d_theta`` rad), with the prior on the variances, started from
        `start` (variances and mixing weight of the previous fit) when given."""
        n0 = self.prior_pairs
        v_rho0, v_th0 = self.range_sum_sigma_m**2, math.radians(self.bearing_sigma_deg) ** 2
        # per-echo variances and the mixing weight of the Gaussian part
        v_rho, v_th, share = (v_rho0, v_th0, 0.5) if start is None else start
        share = min(max(share, 1e-3), 1.0 - 1e-3)
        background = 1.0 / (4.0 * self.window_range_sum_m * self.window_bearing_rad)
        d2 = d * d
        w = np.zeros(d.shape[0])
        for _ in range(50):
            # E step: pair differences have variance 2 sigma^2 per axis.
            g = (np.exp(-0.25 * (d2[:, 0] / v_rho + d2[:, 1] / v_th))
                 / (4.0 * np.pi * math.sqrt(v_rho * v_th)))
            num = share * g
            w = num / (num + (1.0 - share) * background)
            sw = float(w.sum())
            # M step with the conjugate prior on each variance.
            new_rho = (n0 * v_rho0 + 0.5 * float(w @ d2[:, 0])) / (n0 + sw) if n0 + sw > 0 else v_rho
            new_th = (n0 * v_th0 + 0.5 * float(w @ d2[:, 1])) / (n0 + sw) if n0 + sw > 0 else v_th
            new_rho = max(new_rho, self.min_sigma_m**2)
            new_th = max(new_th, self.min_sigma_rad**2)
            share = min(max(sw / d.shape[0], 1e-3), 1.0 - 1e-3)
            done = abs(new_rho - v_rho) <= 1e-3 * v_rho and abs(new_th - v_th) <= 1e-3 * v_th
            v_rho, v_th = new_rho, new_th
            if done:
                break
        return ReceiverNoise(math.sqrt(v_rho), math.degrees(math.sqrt(v_th)), float(w.sum()))

    def sigmas(self, ping: Ping) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """Each detection's current range-sum (m) and bearing (deg) accuracy.

        Returns
        -------
        (ndarray, ndarray), each shape (n,), or None
            None when the ping has no source/receiver positions.
        """
        geo = self._geometry(ping)
        if geo is None:
            return None
        s_rho = np.empty(ping.n)
        s_th = np.empty(ping.n)
        for key, sel in receiver_groups(ping):
            e = self.estimate(key)
            s_rho[sel], s_th[sel] = e.range_sum_sigma_m, e.bearing_sigma_deg
        return s_rho, s_th
