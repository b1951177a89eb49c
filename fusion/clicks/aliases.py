"""One delay per click train: TDOAs that re-pair a stronger TDOA's clicks one click apart.

The smoothed click maps of a periodic click train correlate at the train's delay and again
about one inter-click interval (ICI) either side of it, where sensor i's click n meets sensor
j's click n +- 1; with a jittered ICI only the clicks whose interval happens to equal the mean
match, and such an alias is weaker (fewer matched clicks) but can pass validation at even odds.
The aliases of a train on the pairs of one sensor agree with each other (that sensor's arrivals
all moved by one ICI), and with the train's true TDOAs of the other pairs they make a consistent
set that a fix explains exactly: a ghost source. On the tuning recordings (one whale, floor and
surface echoes, 5 sensors) such ghosts were the false sources.

:func:`train_aliases` marks a TDOA as an alias of a stronger one of the same pair (more matched
clicks) when both sides are the same clicks at another delay: most of its clicks at sensor i are
the stronger TDOA's clicks at sensor i, and most of the arrivals it implies at sensor j
(``t - tau(t)``, along its drift) are arrivals the stronger one implies there. Another whale's
train on the same pair has other clicks at sensor i; an echo path (sensor i's direct clicks
against sensor j's echoes) has other arrivals at sensor j; neither is marked.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from fusion.clicks.window import WindowTdoa

__all__ = ["ALIAS_SHARE", "ALIAS_TOLERANCE_S", "train_aliases"]

#: Share of an alias's clicks that must be the stronger TDOA's clicks, at each sensor.
ALIAS_SHARE = 0.5
#: Largest distance between two times taken as the same click, s.
ALIAS_TOLERANCE_S = 0.5e-3


def _share(a: NDArray[np.float64], b: NDArray[np.float64], tol: float) -> float:
    """Fraction of the times `a` within `tol` of a time of `b`."""
    if a.size == 0 or b.size == 0:
        return 0.0
    b = np.sort(b)
    i = np.searchsorted(b, a)
    near = np.minimum(np.abs(a - b[np.clip(i - 1, 0, b.size - 1)]),
                      np.abs(a - b[np.clip(i, 0, b.size - 1)]))
    return float(np.mean(near <= tol))


def _at_j(d: WindowTdoa) -> NDArray[np.float64]:
    """Arrivals at sensor j that `d` implies: ``t - tau(t)`` for its clicks t at sensor i."""
    t = d.click_times_s
    ref = d.t_s if np.isfinite(d.t_s) else 0.0
    return t - (d.tau_s + d.rate * (t - ref))


def train_aliases(
    tdoas: Sequence[WindowTdoa], *, share: float = ALIAS_SHARE,
    tolerance_s: float = ALIAS_TOLERANCE_S,
) -> NDArray[np.bool_]:
    """Which TDOAs re-pair the clicks of a stronger TDOA of the same pair at another delay.

    Parameters
    ----------
    tdoas : sequence of WindowTdoa
        One window's candidate TDOAs; only those that pass validation are compared (a marked
        TDOA passed; its stronger one passed too).
    share : float, optional
        Least fraction of its clicks that must be the stronger one's, at sensor i and at j.
    tolerance_s : float, optional
        Largest distance between two times taken as the same click, s; delays closer than
        this are one delay, not an alias.

    Returns
    -------
    ndarray of bool, shape (len(tdoas),)
        True for an alias.
    """
    out = np.zeros(len(tdoas), dtype=bool)
    by_pair: dict[tuple[int, int], list[int]] = {}
    for k, d in enumerate(tdoas):
        if d.passes and d.click_times_s.size:
            by_pair.setdefault(tuple(d.pair), []).append(k)
    for ks in by_pair.values():
        for b in ks:
            weak = tdoas[b]
            for a in ks:
                strong = tdoas[a]
                if (a == b or strong.n_clicks <= weak.n_clicks
                        or abs(strong.tau_s - weak.tau_s) <= tolerance_s):
                    continue
                if (_share(weak.click_times_s, strong.click_times_s, tolerance_s) >= share
                        and _share(_at_j(weak), _at_j(strong), tolerance_s) >= share):
                    out[b] = True
                    break
    return out
