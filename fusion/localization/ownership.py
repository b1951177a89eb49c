"""Which TDOAs a candidate holds: eq. (20)-(21) weights, the per-pair cap, merging, dropping.

The pieces of the competition (:mod:`fusion.localization.competition`) that judge a candidate's share
of a window's TDOAs: the delay-fit and association weights of eq. (20)-(21), the rank of the
sensor pairs a set of TDOAs spans (three independent pairs fix a 3-D position), the cap of one
TDOA's worth of weight per sensor pair, and the rule that keeps a candidate only while its
associated TDOAs can fix a source.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (20)-(21) and paragraph [0047].
"""

from __future__ import annotations

from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from fusion.localization.competition_settings import CompetitionSettings
    from fusion.localization.window_tdoas import WindowTdoas

__all__ = [
    "association_weights",
    "cap_per_pair",
    "holds_a_source",
    "independent_pairs",
    "pair_ids",
    "same_source",
    "supported_weights",
]


def independent_pairs(pairs: NDArray[np.intp], rows: NDArray[np.bool_]) -> int:
    """Rank of the incidence of the selected pairs: sensors they touch minus their components.

    (The number of independent TDOAs: a spanning forest of the pair graph.)
    """
    selected = np.asarray(pairs)[rows]
    return _forest_size(selected.astype(np.intp, copy=False).tobytes())


@lru_cache(maxsize=4096)
def _forest_size(selected: bytes) -> int:
    """Edges of a spanning forest of the pairs (i, j) packed in `selected` (intp bytes)."""
    parent: dict[int, int] = {}

    def root(i: int) -> int:
        while parent.setdefault(i, i) != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    rank = 0
    for i, j in np.frombuffer(selected, dtype=np.intp).reshape(-1, 2).tolist():
        ri, rj = root(i), root(j)
        if ri != rj:
            parent[ri] = rj
            rank += 1
    return rank


def pair_ids(pairs: NDArray[np.intp]) -> NDArray[np.intp]:
    """Id of the unordered sensor pair of each TDOA."""
    lo, hi = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
    return np.unique(lo * (hi.max() + 1) + hi, return_inverse=True)[1].reshape(-1)


def cap_per_pair(w: NDArray[np.float64], pair_id: NDArray[np.intp]) -> NDArray[np.float64]:
    """Scale each candidate's weights on one pair down to a total of at most one."""
    totals = np.zeros((w.shape[0], int(pair_id.max()) + 1))
    np.add.at(totals.T, pair_id, w.T)
    return w / np.maximum(totals[:, pair_id], 1.0)




def association_weights(
    residuals: ArrayLike, sigma_t: ArrayLike, alpha: ArrayLike | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Delay-fit weights ``beta`` (eq. 20) and association weights ``gamma`` (eq. 21).

    Parameters
    ----------
    residuals : array_like, shape (K, M)
        ``d_m(x_k) - tau_m`` of each TDOA at each candidate, s.
    sigma_t : float or array_like, broadcastable to (K, M)
        Delay scale ``sigma_t`` of eq. (20), s.
    alpha : array_like, shape (M, M), optional
        Cross-pair association (symmetric); None gives ``gamma = beta``.

    Returns
    -------
    beta : ndarray, shape (K, M)
        ``exp(-(d_m - tau_m)^2 / (sigma_t^2 / 4))``.
    gamma : ndarray, shape (K, M)
        ``sum_l (1 - exp(-alpha_ml / 4)) beta_kl beta_km``.

    Examples
    --------
    >>> alpha = 1e9 * (1.0 - np.eye(3))  # three strongly associated TDOAs
    >>> beta, gamma = association_weights([[0.0, 0.0, 2.0]], 1.0, alpha)
    >>> np.round(gamma, 6)  # two fitting TDOAs confirm each other; the third fits nothing
    array([[1., 1., 0.]])
    """
    r = np.asarray(residuals, dtype=float)
    beta = np.exp(-(r * r) / (np.asarray(sigma_t, dtype=float) ** 2 / 4.0))  # eq. (20)
    if alpha is None:
        return beta, beta
    link = 1.0 - np.exp(-np.asarray(alpha, dtype=float) / 4.0)  # 1 - exp(-alpha_ml / 4)
    return beta, beta * (beta @ link)  # eq. (21), alpha symmetric


def supported_weights(w: NDArray[np.float64], alpha: NDArray[np.float64] | None,
                      min_alpha_link: float) -> NDArray[np.float64]:
    """A candidate's TDOA weights, zero where a TDOA is associated with none of its others.

    With ``alpha``, TDOA ``m`` counts only if some other TDOA of weight > 0.5 is linked to it
    (``alpha_ml >= min_alpha_link``): a true source's TDOAs share its clicks, a chance fit of a
    clutter TDOA does not. Without ``alpha`` the weights are returned unchanged.
    """
    if alpha is None:
        return w
    held = w > 0.5
    linked = np.any((np.asarray(alpha) >= min_alpha_link) & held[None, :], axis=1)
    return np.where(linked, w, 0.0)


#: Unknowns of a source position (x, y, z).
POSITION_UNKNOWNS = 3


def holds_a_source(w: NDArray[np.float64], pairs: NDArray[np.intp],
                   alpha: NDArray[np.float64] | None, cfg: CompetitionSettings) -> bool:
    """Whether weights `w` hold enough associated TDOAs to fix a source (the drop rule).

    Enough weight (``min_weight``), TDOAs of weight > 0.5 spanning ``min_independent``
    independent pairs, and at least ``3 + min_redundant_tdoas`` of them: a position has three
    unknowns, so a fix on three TDOAs fits them exactly whatever made them.
    """
    ws = supported_weights(w, alpha, cfg.min_alpha_link)
    held = ws > 0.5
    return bool(ws.sum() >= cfg.min_weight
                and int(held.sum()) >= POSITION_UNKNOWNS + cfg.min_redundant_tdoas
                and independent_pairs(pairs, held) >= cfg.min_independent)


def same_source(
    tdoas: WindowTdoas, xa: NDArray, xb: NDArray, wa: NDArray, wb: NDArray, scale: NDArray,
    settings: CompetitionSettings, *, settled: bool,
    delays: tuple[NDArray, NDArray] | None = None,
) -> bool:
    """Whether two candidates explain the same TDOAs.

    Close in delay space (at the sharper candidate's scale), or, once both are annealed,
    splitting the same TDOAs between them (while annealing, broad candidates share naturally).
    `delays`, when given, are ``tdoas.predicted(xa)`` and ``tdoas.predicted(xb)``.
    """
    union = np.maximum(wa, wb)
    da, db = (tdoas.predicted(xa), tdoas.predicted(xb)) if delays is None else delays
    e = (da - db) / scale
    if union.sum() > 0:
        rms = float(np.sqrt(np.sum(union * e * e) / union.sum()))
    else:
        rms = float(np.sqrt(np.mean(e * e)))
    small = min(wa.sum(), wb.sum())
    shared = float(np.minimum(wa, wb).sum() / small) if small > 0 else 0.0
    return rms < settings.merge_sigmas or (settled and shared > settings.max_overlap)
