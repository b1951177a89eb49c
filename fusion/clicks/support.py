"""TDOAs of a weakly heard sensor admitted by closure with the validated ones.

A whale a few decibels below the others, or far from one hydrophone, is detected on that
hydrophone in only part of its clicks (8-13 of 25-40 in a 12-s window on the click-shape
tuning and report seeds of ``benchmarks/bench_localize_baseline.py --vary-only click-shape``).
The SCM2 of such a partial train scores near even odds (LLR -1.7 to 0.4), below the validation
bar, while the pairs among the three well-heard hydrophones pass. Three TDOAs of three sensors
hold two independent delays: no 3-D fix, and the window is lost.

:func:`closure_support` admits such TDOAs where, and only where, the window's validated TDOAs
span fewer than four sensors (no fix is possible without them): a candidate on pair (m, k),
sensor k not spanned, m spanned, that failed on its LLR alone (not an alias of a stronger train)
and scores at least :data:`SUPPORT_MIN_LLR`, is admitted when another such candidate (m', k)
closes with it and a validated TDOA of (m, m') -- ``tau_mk - tau_m'k = tau_mm'`` for one click
(each delay moved along its drift), within :data:`CLOSURE_TOL_S`, the candidates refined on
the waveforms first -- and each of the two shares
at least :data:`SUPPORT_MIN_ALPHA` clicks with that validated TDOA at their common sensor (the
association across pairs, eq. 13 of *Localization of Short Duration Periodic Signals*). Sensor
k's clicks are then placed consistently by two validated sensors, which a chance peak does not
do. ``docs/localization.md`` section 15.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from fusion.clicks.associate import TdoaClicks, click_match

__all__ = ["CLOSURE_TOL_S", "SUPPORT_MIN_ALPHA", "SUPPORT_MIN_LLR", "closure_support"]

#: Lowest LLR of a candidate admitted by closure (the partial trains of the tuning seeds
#: scored -1.7 to 0.4).
SUPPORT_MIN_LLR = -2.0
#: Closure tolerance of the three refined delays of a triangle, taken for one click, s (their
#: sigmas are 0.1-1 us; the click-map grid's delays are off by up to ~1 ms).
CLOSURE_TOL_S = 5e-5
#: Clicks a supporting candidate shares with the validated TDOA at their common sensor (eq. 13).
SUPPORT_MIN_ALPHA = 3.0


def _delay(t: TdoaClicks, a: int, b: int, u_a: float, t_ref: float) -> float:
    """``t_a - t_b`` of the click arriving at sensor a at `u_a`, from a TDOA on (a, b) or (b, a)
    that holds at `t_ref` (arrival at its first sensor) and drifts at its ``rate``."""
    if t.pair == (a, b):
        return t.tau_s + t.rate * (u_a - t_ref)
    u_b = u_a + t.tau_s + t.rate * (u_a - t_ref)  # the arrival at b (t_b = t_a - tau_ab)
    return -(t.tau_s + t.rate * (u_b - t_ref))


def closure_support(
    tdoas: Sequence[TdoaClicks],
    passes: Sequence[bool],
    eligible: Sequence[bool],
    llr: Sequence[float],
    *,
    min_llr: float = SUPPORT_MIN_LLR,
    tol_s: float = CLOSURE_TOL_S,
    min_alpha: float = SUPPORT_MIN_ALPHA,
    sigma_t_s: float = 1e-3,
    t_ref_s: float = 0.0,
) -> NDArray[np.bool_]:
    """Which candidates of one window closure admits (see the module docstring).

    Parameters
    ----------
    tdoas : sequence of TdoaClicks, length M
        The window's candidates (click-map delays and click times at the pair's first sensor).
    passes : sequence of bool, length M
        Validated (LLR at the bar, not an alias).
    eligible : sequence of bool, length M
        May be admitted: failed on its LLR alone (not an alias).
    llr : sequence of float, length M
        Validation log-likelihood ratios.
    min_llr, tol_s, min_alpha : float, optional
        :data:`SUPPORT_MIN_LLR`, :data:`CLOSURE_TOL_S`, :data:`SUPPORT_MIN_ALPHA`.
    sigma_t_s : float, optional
        Click-match tolerance, s (eq. 13).
    t_ref_s : float, optional
        Time at which every TDOA holds (the arrival at its pair's first sensor, the window
        centre); with each TDOA's ``rate`` the three delays of a triangle are taken for one
        click (its arrival at the first sensor at `t_ref_s`).

    Returns
    -------
    ndarray of bool, shape (M,)
        True for the candidates admitted; all False when the validated TDOAs span four
        sensors or more.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(30) * 0.4 + 0.1       # clicks at sensor 0
    >>> arrival = {0: 0.0, 1: 0.21, 2: 0.35, 3: 0.12}  # delay of each sensor after sensor 0
    >>> def d(i, j, every=1):
    ...     return TdoaClicks((i, j), arrival[i] - arrival[j], t[::every] + arrival[i])
    >>> cands = [d(0, 1), d(0, 2), d(1, 2), d(0, 3, 3), d(1, 3, 3), d(2, 3, 3)]
    >>> closure_support(cands, [1, 1, 1, 0, 0, 0], [0, 0, 0, 1, 1, 1], [9, 9, 9, -1, 0, -1])
    array([False, False, False,  True,  True,  True])
    """
    n = len(tdoas)
    ok = np.asarray(passes, dtype=bool)
    can = (np.asarray(eligible, dtype=bool) & ~ok
           & (np.asarray(llr, dtype=float) >= min_llr))
    out = np.zeros(n, dtype=bool)
    spanned = {s for k in np.flatnonzero(ok) for s in tdoas[k].pair}
    if len(spanned) >= 4 or len(spanned) < 2:
        return out
    valid = [k for k in np.flatnonzero(ok)]
    for a in np.flatnonzero(can):
        for b in np.flatnonzero(can):
            if b <= a:
                continue
            pa, pb = set(tdoas[a].pair), set(tdoas[b].pair)
            shared = pa & pb
            if len(shared) != 1:
                continue
            (k,) = shared
            (m1,), (m2,) = pa - shared, pb - shared
            if k in spanned or m1 not in spanned or m2 not in spanned:
                continue
            for v in valid:
                if set(tdoas[v].pair) != {m1, m2}:
                    continue
                # one click: at m1 at t_ref, at m2 tau_{m1 m2} later (t_m2 = t_m1 - tau)
                d12 = _delay(tdoas[v], m1, m2, t_ref_s, t_ref_s)
                closure = (_delay(tdoas[a], m1, k, t_ref_s, t_ref_s)
                           - _delay(tdoas[b], m2, k, t_ref_s - d12, t_ref_s) - d12)
                if abs(closure) > tol_s:
                    continue
                if (click_match(tdoas[a].times_at(m1), tdoas[v].times_at(m1), sigma_t_s)
                        >= min_alpha
                        and click_match(tdoas[b].times_at(m2), tdoas[v].times_at(m2), sigma_t_s)
                        >= min_alpha):
                    out[a] = out[b] = True
    return out
