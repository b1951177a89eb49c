"""TDOA association by click matching: across time (step 52), across sensor pairs (step 54).

Implements paragraphs [0039]-[0043] of *Localization of Short Duration Periodic Signals*
(Baggenstoss, NUWC 102089). Each TDOA carries the source click times located in its SCM2
(second-order smoothed click map). Two TDOAs that see the same whale see the same clicks, so
the soft count of matching click times (:func:`click_match`, eq. 12 / 13) measures whether they
belong together:

* across time (:class:`TimeAssociator`, eq. 12): a TDOA of the current window links to one of
  the same sensor pair in the previous window when enough clicks match and the delay barely
  moved; a TDOA with a link is *confirmed* (seen in two consecutive updates);
* across pairs (:func:`cross_pair_alpha`, eq. 13): ``alpha[l, m]`` counts the matching clicks of
  two TDOAs that share exactly one sensor, after both click lists are referred to that sensor;
* across a sensor triangle (:func:`closure_check`, not in the text): TDOAs of one source on
  pairs ``(a, b)``, ``(b, c)``, ``(a, c)`` satisfy ``tau_ab + tau_bc - tau_ac = 0``.

Conventions: a TDOA of pair ``(i, j)`` is ``tau = t_i - t_j``; its click times are times at
sensor ``i`` (the SCM2 is referenced to the first sensor of the pair, paragraph [0036]); the
same clicks at sensor ``j`` are ``t_j = t_i - tau``. Click times are absolute (seconds from the
start of the audio), so clicks of overlapping windows compare directly — the window shift of
paragraph [0039] is already accounted for.

Decisions where the text is silent (keyword options):

* **sigma_t** (eq. 12, 13) defaults to 1 ms: the SCM2 pulse is about 5 ms wide on its 3 kHz grid
  and a click's SCM2 time moves by half of any change of the TDOA.
* **max_dtau** is 3 ms at the text's 2 s update and scales in proportion to the update period
  (the delay drifts with the source's motion, which grows with the time between updates);
  an explicit value overrides it.
* **One-to-one links** across time: among the admissible pairs (same sensor pair,
  ``beta > beta_min``, ``|dtau| < max_dtau``), the assignment maximising the total ``beta``
  (:func:`scipy.optimize.linear_sum_assignment`).

Examples
--------
>>> import numpy as np
>>> t = np.arange(20) * 0.37
>>> round(click_match(t, t + 1e-4, 1e-3), 2)
19.9
"""

from __future__ import annotations

import itertools
import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from fusion._validation import check_positive
from fusion.clicks.types import frozen_array

__all__ = [
    "ClosureCheck",
    "TdoaClicks",
    "TimeAssociation",
    "TimeAssociator",
    "TimeLink",
    "click_match",
    "closure_check",
    "cross_pair_alpha",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class TdoaClicks:
    """A TDOA with the source click times of its SCM2.

    Attributes
    ----------
    pair : tuple of int
        Sensor indices ``(i, j)``, ``i != j``.
    tau_s : float
        ``t_i - t_j``, s.
    click_times_s : ndarray, shape (n,)
        Source click times located in the SCM2, referenced to sensor ``i``: s from the start of
        the audio.
    sigma_s : float or None
        Standard deviation of `tau_s`, s, when known (sets the closure tolerance).
    rate : float
        Drift ``d tau / dt`` of the TDOA through its window, s/s, when measured (0 otherwise);
        the time association compares delays after moving each by its drift to the midpoint
        between the two windows.
    """

    pair: tuple[int, int]
    tau_s: float
    click_times_s: NDArray[np.float64]
    sigma_s: float | None = None
    rate: float = 0.0

    def __post_init__(self) -> None:
        i, j = (int(k) for k in self.pair)
        if i == j or i < 0 or j < 0:
            raise ValueError(f"pair must hold two different sensor indices >= 0, got {self.pair}")
        object.__setattr__(self, "pair", (i, j))
        object.__setattr__(self, "tau_s", float(self.tau_s))
        if not np.isfinite(self.tau_s):
            raise ValueError(f"tau_s must be finite, got {self.tau_s}")
        times = frozen_array(self.click_times_s)
        if times.ndim != 1 or not np.all(np.isfinite(times)):
            raise ValueError("click_times_s must be a 1-D array of finite times")
        object.__setattr__(self, "click_times_s", times)
        if self.sigma_s is not None:
            object.__setattr__(self, "sigma_s", check_positive("sigma_s", self.sigma_s))
        object.__setattr__(self, "rate", float(self.rate))
        if not np.isfinite(self.rate):
            raise ValueError(f"rate must be finite, got {self.rate}")

    def times_at(self, sensor: int) -> NDArray[np.float64]:
        """The click times referenced to `sensor` (one of :attr:`pair`), s."""
        if sensor == self.pair[0]:
            return self.click_times_s
        if sensor == self.pair[1]:
            return self.click_times_s - self.tau_s  # t_j = t_i - tau
        raise ValueError(f"sensor {sensor} is not in pair {self.pair}")

    def reversed(self) -> TdoaClicks:
        """The same measurement on pair ``(j, i)``: ``-tau``, click times at sensor ``j``."""
        return TdoaClicks((self.pair[1], self.pair[0]), -self.tau_s, self.times_at(self.pair[1]),
                          self.sigma_s, -self.rate)


def click_match(t_p: ArrayLike, t_q: ArrayLike, sigma_t: float, *, cutoff: float = 6.0) -> float:
    """Soft count of matching click times of two lists (eq. 12 and 13).

    Parameters
    ----------
    t_p : array_like, shape (n_p,)
        Click times, s (any order).
    t_q : array_like, shape (n_q,)
        Click times, s, on the same reference.
    sigma_t : float
        Time tolerance (standard deviation), s.
    cutoff : float, optional
        Pairs more than ``cutoff * sigma_t`` apart are left out (each would add less than
        ``exp(-cutoff^2 / 2)``, 1.5e-8 at the default).

    Returns
    -------
    float
        ``sum_k sum_l exp(-(t_p[k] - t_q[l])^2 / (2 sigma_t^2))``: about the number of clicks
        the lists share.

    Notes
    -----
    *Localization of Short Duration Periodic Signals*, eq. (12) (beta, across time) and eq. (13)
    (alpha, across pairs). Only pairs within the cutoff are formed: `t_q` is sorted and each
    ``t_p`` finds its window by :func:`numpy.searchsorted`, so the cost is ``O((n_p + n_q)
    log n_q)`` plus the number of close pairs, not ``n_p * n_q``.
    """
    sig = check_positive("sigma_t", sigma_t)
    cut = check_positive("cutoff", cutoff) * sig
    p = np.asarray(t_p, dtype=float).ravel()
    q = np.sort(np.asarray(t_q, dtype=float).ravel())
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))):
        raise ValueError("click times must be finite")
    if p.size == 0 or q.size == 0:
        return 0.0
    margin = cut * (1.0 + 1e-9)  # windows a hair wide; the exact |d| <= cut test below is symmetric
    lo = np.searchsorted(q, p - margin, side="left")
    hi = np.searchsorted(q, p + margin, side="right")
    counts = hi - lo
    ip = np.repeat(np.arange(p.size), counts)
    iq = lo[ip] + np.arange(ip.size) - np.repeat(np.cumsum(counts) - counts, counts)
    d = p[ip] - q[iq]
    d = d[np.abs(d) <= cut]
    return float(np.sum(np.exp(-0.5 * (d / sig) ** 2)))  # eq. (12) / (13)


# --------------------------------------------------------------------------------------------
# across time (step 52)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TimeLink:
    """A sequential association of two TDOAs of one sensor pair.

    Attributes
    ----------
    previous : int
        Index of the TDOA in the previous window's list.
    current : int
        Index of the TDOA in the current window's list.
    beta : float
        Click-match count (eq. 12).
    dtau_s : float
        Current minus previous TDOA, in the current TDOA's pair orientation, s.
    """

    previous: int
    current: int
    beta: float
    dtau_s: float


@dataclass(frozen=True)
class TimeAssociation:
    """Result of :meth:`TimeAssociator.associate`.

    Attributes
    ----------
    links : tuple of TimeLink
        One-to-one links, by increasing current index.
    beta : ndarray, shape (n_previous, n_current)
        Click-match count of every previous/current pair of the same sensor pair (0 otherwise).
    dtau_s : ndarray, shape (n_previous, n_current)
        TDOA change in the current orientation, s (NaN across different sensor pairs).
    confirmed : ndarray of bool, shape (n_current,)
        Current TDOAs with a link (seen in two consecutive updates).
    previous_linked : ndarray of bool, shape (n_previous,)
        Previous TDOAs with a link.
    """

    links: tuple[TimeLink, ...]
    beta: NDArray[np.float64]
    dtau_s: NDArray[np.float64]
    confirmed: NDArray[np.bool_]
    previous_linked: NDArray[np.bool_]


class TimeAssociator:
    """Links the TDOAs of consecutive windows that share their clicks (step 52, eq. 12).

    Parameters
    ----------
    sigma_t_s : float, optional
        Time tolerance of the click match, s.
    beta_min : float, optional
        A link needs ``beta > beta_min`` (the text's 7 matching clicks).
    update_period_s : float, optional
        Time between consecutive windows, s.
    max_dtau_s : float, optional
        A link needs ``|dtau| < max_dtau_s``; default 3 ms scaled by ``update_period_s / 2 s``.
        ``dtau`` is the change of the delay after each TDOA is moved by its measured drift
        (:attr:`TdoaClicks.rate`) to the midpoint between the windows: the text's plain change
        when no drift is known.

    Notes
    -----
    *Localization of Short Duration Periodic Signals*, paragraphs [0040]-[0041].

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(30) * 0.37
    >>> prev = [TdoaClicks((0, 1), 0.5000, t)]
    >>> cur = [TdoaClicks((0, 1), 0.5004, t + 2e-4), TdoaClicks((0, 2), 0.3, t)]
    >>> TimeAssociator().associate(prev, cur).confirmed.tolist()
    [True, False]
    """

    def __init__(
        self,
        *,
        sigma_t_s: float = 1e-3,
        beta_min: float = 7.0,
        update_period_s: float = 2.0,
        max_dtau_s: float | None = None,
    ) -> None:
        self.sigma_t_s = check_positive("sigma_t_s", sigma_t_s)
        self.beta_min = check_positive("beta_min", beta_min, allow_zero=True)
        self.update_period_s = check_positive("update_period_s", update_period_s)
        self.max_dtau_s = (3e-3 * self.update_period_s / 2.0 if max_dtau_s is None
                           else check_positive("max_dtau_s", max_dtau_s))

    def associate(self, previous: Sequence[TdoaClicks], current: Sequence[TdoaClicks]) -> TimeAssociation:
        """Link the current window's TDOAs to the previous window's.

        Parameters
        ----------
        previous : sequence of TdoaClicks
            TDOAs of the previous window.
        current : sequence of TdoaClicks
            TDOAs of the current window.

        Returns
        -------
        TimeAssociation
        """
        n_p, n_c = len(previous), len(current)
        beta = np.zeros((n_p, n_c))
        dtau = np.full((n_p, n_c), np.nan)
        for (a, prev), (b, cur) in itertools.product(enumerate(previous), enumerate(current)):
            if set(prev.pair) != set(cur.pair):
                continue
            prev_c = prev if prev.pair == cur.pair else prev.reversed()  # current orientation
            # delays compared at the midpoint between the windows, each moved by its own drift
            # (a source moving at 1-2 m/s drifts a TDOA by up to 2.7 ms per second)
            half = 0.5 * self.update_period_s
            dtau[a, b] = (cur.tau_s - cur.rate * half) - (prev_c.tau_s + prev_c.rate * half)
            beta[a, b] = click_match(prev_c.click_times_s, cur.click_times_s, self.sigma_t_s)
        with np.errstate(invalid="ignore"):
            admissible = (beta > self.beta_min) & (np.abs(dtau) < self.max_dtau_s)
        links: list[TimeLink] = []
        if np.any(admissible):
            rows, cols = linear_sum_assignment(np.where(admissible, -beta, 0.0))
            for a, b in zip(rows, cols, strict=True):
                if admissible[a, b]:
                    links.append(TimeLink(int(a), int(b), float(beta[a, b]), float(dtau[a, b])))
        links.sort(key=lambda link: link.current)
        confirmed = np.zeros(n_c, dtype=bool)
        prev_linked = np.zeros(n_p, dtype=bool)
        confirmed[[link.current for link in links]] = True
        prev_linked[[link.previous for link in links]] = True
        logger.debug("time association: %d of %d current TDOAs linked", len(links), n_c)
        return TimeAssociation(tuple(links), beta, dtau, confirmed, prev_linked)


# --------------------------------------------------------------------------------------------
# across pairs (step 54)
# --------------------------------------------------------------------------------------------
def cross_pair_alpha(tdoas: Sequence[TdoaClicks], *, sigma_t_s: float = 1e-3) -> NDArray[np.float64]:
    """Association measure ``alpha[l, m]`` of the TDOAs of one window (eq. 13).

    Parameters
    ----------
    tdoas : sequence of TdoaClicks, length M
        TDOAs measured on the sensor pairs at about the same time.
    sigma_t_s : float, optional
        Time tolerance of the click match, s.

    Returns
    -------
    ndarray, shape (M, M)
        Symmetric, zero diagonal; 0 for TDOAs that do not share exactly one sensor, else the
        click-match count of their click times referred to the shared sensor.

    Notes
    -----
    *Localization of Short Duration Periodic Signals*, paragraphs [0042]-[0043], eq. (13).
    """
    sig = check_positive("sigma_t_s", sigma_t_s)
    m = len(tdoas)
    alpha = np.zeros((m, m))
    for l_, k in itertools.combinations(range(m), 2):
        shared = set(tdoas[l_].pair) & set(tdoas[k].pair)
        if len(shared) != 1:
            continue
        s = shared.pop()
        alpha[l_, k] = alpha[k, l_] = click_match(tdoas[l_].times_at(s), tdoas[k].times_at(s), sig)
    return alpha


# --------------------------------------------------------------------------------------------
# closure over sensor triangles
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ClosureCheck:
    """Result of :func:`closure_check`, one entry per TDOA.

    Attributes
    ----------
    residual_s : ndarray, shape (M,)
        ``|tau_ab + tau_bc - tau_ac|`` of the TDOA's best triple (smallest residual over
        tolerance), s; NaN for a TDOA in no qualifying triple.
    tolerance_s : ndarray, shape (M,)
        Tolerance of that triple, s (NaN if none).
    n_triples : ndarray of int, shape (M,)
        Qualifying triples the TDOA takes part in.
    consistent : ndarray of bool, shape (M,)
        ``residual_s <= tolerance_s``: some triple closes. False where ``n_triples == 0``.
    """

    residual_s: NDArray[np.float64]
    tolerance_s: NDArray[np.float64]
    n_triples: NDArray[np.int_]
    consistent: NDArray[np.bool_]

    @property
    def tested(self) -> NDArray[np.bool_]:
        """TDOAs in at least one qualifying triple (the others are neither confirmed nor refuted)."""
        return self.n_triples > 0


def closure_check(
    tdoas: Sequence[TdoaClicks],
    alpha: ArrayLike | None = None,
    *,
    alpha_min: float = 3.0,
    sigma_t_s: float = 1e-3,
    tol_s: float | None = None,
    n_sigma: float = 3.0,
    default_tol_s: float = 5e-4,
) -> ClosureCheck:
    """Check that TDOAs on the three pairs of a sensor triangle add up: ``tau_ab + tau_bc = tau_ac``.

    Parameters
    ----------
    tdoas : sequence of TdoaClicks, length M
        TDOAs of one window, on any pairs and in any orientation.
    alpha : array_like, shape (M, M), optional
        Cross-pair association (:func:`cross_pair_alpha`); computed with `sigma_t_s` if omitted.
    alpha_min : float, optional
        A triple qualifies when its three TDOAs are connected by association: at least two of its
        three ``alpha`` values reach `alpha_min`.
    sigma_t_s : float, optional
        Click-match tolerance used when `alpha` is computed here, s.
    tol_s : float, optional
        Fixed closure tolerance, s, for every triple; overrides the rules below.
    n_sigma : float, optional
        With all three TDOAs' ``sigma_s`` known, a triple's tolerance is
        ``n_sigma * sqrt(sum of the three variances)``.
    default_tol_s : float, optional
        Tolerance of a triple with a TDOA of unknown ``sigma_s``, s.

    Returns
    -------
    ClosureCheck

    Notes
    -----
    Not part of the method text: a geometric consistency check on top of its association
    measure (eq. 13). For arrival times ``t_a, t_b, t_c`` of one click, ``(t_a - t_b) + (t_b -
    t_c) - (t_a - t_c) = 0`` exactly; a TDOA on pair ``(j, i)`` enters as ``-tau``. Two, not
    three, associated pairs qualify a triple because a wrong ``tau`` misplaces its own clicks at
    its second sensor and so breaks one of its two alphas — requiring all three would hide the
    very TDOAs the check is meant to catch.
    """
    m = len(tdoas)
    if alpha is None:
        alpha_arr = cross_pair_alpha(tdoas, sigma_t_s=sigma_t_s)
    else:
        alpha_arr = np.asarray(alpha, dtype=float)
        if alpha_arr.shape != (m, m):
            raise ValueError(f"alpha must have shape ({m}, {m}), got {alpha_arr.shape}")
    a_min = check_positive("alpha_min", alpha_min, allow_zero=True)
    k_sig = check_positive("n_sigma", n_sigma)
    tol_default = check_positive("default_tol_s", default_tol_s)
    tol_fixed = None if tol_s is None else check_positive("tol_s", tol_s)

    # canonical orientation (low, high): tau(low, high) = +-tau
    key = [tuple(sorted(t.pair)) for t in tdoas]
    tau_c = np.array([t.tau_s if t.pair[0] < t.pair[1] else -t.tau_s for t in tdoas])
    var = np.array([np.nan if t.sigma_s is None else t.sigma_s**2 for t in tdoas])
    groups: dict[tuple[int, int], list[int]] = {}
    for idx, k in enumerate(key):
        groups.setdefault(k, []).append(idx)
    sensors = sorted({s for k in key for s in k})

    triples = []
    for a, b, c in itertools.combinations(sensors, 3):
        if (a, b) in groups and (b, c) in groups and (a, c) in groups:
            grid = np.meshgrid(groups[(a, b)], groups[(b, c)], groups[(a, c)], indexing="ij")
            triples.append(np.stack([g.ravel() for g in grid], axis=1))
    tri = np.concatenate(triples) if triples else np.zeros((0, 3), dtype=int)
    i_ab, i_bc, i_ac = tri.T
    res = np.abs(tau_c[i_ab] + tau_c[i_bc] - tau_c[i_ac])  # closure residual
    n_assoc = ((alpha_arr[i_ab, i_bc] >= a_min).astype(int) + (alpha_arr[i_ab, i_ac] >= a_min)
               + (alpha_arr[i_bc, i_ac] >= a_min))
    keep = n_assoc >= 2
    tri, res = tri[keep], res[keep]
    if tol_fixed is not None:
        tol = np.full(res.shape, tol_fixed)
    else:
        tot = var[tri].sum(axis=1)
        tol = np.where(np.isfinite(tot), k_sig * np.sqrt(tot), tol_default)

    residual = np.full(m, np.nan)
    tolerance = np.full(m, np.nan)
    n_triples = np.bincount(tri.ravel(), minlength=m)
    if tri.size:
        member = tri.T.ravel()  # every (TDOA, triple) membership
        ratio = np.tile(res / tol, 3)
        order = np.lexsort((ratio, member))
        first = order[np.unique(member[order], return_index=True)[1]]
        best = first % res.size
        residual[member[first]] = res[best]
        tolerance[member[first]] = tol[best]
    with np.errstate(invalid="ignore"):
        consistent = residual <= tolerance
    return ClosureCheck(residual, tolerance, n_triples, consistent)
