"""Association stage of the multistatic tracker: fuzzy rank of gated pairs, threshold, assignment.

Sections 3-7 of "Target tracking using fuzzy logic association": for the (track, detection)
pairs inside the chi-square gate, the rule base ranks each detection from the likelihood ratio
``L`` and the clues present in the data (classifier score, SNR, equivalent aspect angle, distance
to the nearest clutter-map hotspot); rules whose inputs are absent are left out
(:class:`PairRanker`). A pair ranked below the rank threshold is never associated (Section 7:
clutter tracks did not form because "the ranks were all too low"); the threshold is read off the
rule base for the clues the pair actually has (:func:`derived_min_rank`): the rank of a detection
at the edge of the acceptance region, ``L = 0.25`` (Mahalanobis ``d2`` = 2.77, inside which a
true detection falls with probability 0.75), with every other present clue at its neutral
(crossover) value. So positions-only data are held to the likelihood rules' own standard, not to
a threshold calibrated with every clue.

Each track takes its highest-ranked detection; conflicts (two tracks wanting one detection) are
resolved by an assignment that maximises the summed rank (:func:`assign`). Where the paper is
silent: confirmed tracks are assigned first, tentative tracks then share the remaining detections
(:func:`assign_by_priority`), so a fresh clutter track cannot take a confirmed track's detection.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from fusion.active.bistatic import equivalent_aspect_deg
from fusion.active.types import POSITION_CLUES, Ping

__all__ = [
    "CLUE_NAMES",
    "EDGE_LIKELIHOOD",
    "PairRanker",
    "assign",
    "assign_by_priority",
    "derived_min_rank",
    "neutral_value",
]

logger = logging.getLogger(__name__)

#: Clue inputs of the fuzzy rule base besides the likelihood.
CLUE_NAMES: tuple[str, ...] = ("score", "snr_db", "aspect_deg", "hotspot_distance_m")

#: Likelihood ratio at the edge of the acceptance region (the crossover of the default
#: "unlikely" set, which falls from 1 at L = 0.1 to 0 at L = 0.4): a true detection has a
#: larger L with probability 0.75 (L is uniform on (0, 1] for true detections).
EDGE_LIKELIHOOD: float = 0.25


def neutral_value(variable: object) -> float:
    """Value of an input variable at which its terms say the least: its crossover point.

    Parameters
    ----------
    variable : LinguisticVariable
        A fuzzy input variable (``name``, ``universe``, ``terms``).

    Returns
    -------
    float
        The point of the universe where the largest ``|mu_t(x) - 0.5|`` over the variable's
        terms is smallest (for two complementary terms, where both are 1/2; for a single term,
        where it is 1/2); the smallest such point on ties. Candidates are a 2001-point grid of
        the universe and every point where a piecewise-linear term crosses 1/2.

    Examples
    --------
    >>> from fusion.active.rulebase import default_variables
    >>> [neutral_value(v) for v in default_variables()[1:]]
    [0.65, 70.0, 16.0, 300.0]
    """
    low, high = (float(v) for v in variable.universe)  # type: ignore[attr-defined]
    terms = list(variable.terms.values())  # type: ignore[attr-defined]
    cands = [np.linspace(low, high, 2001)]
    for mf in terms:
        kn = mf.knots()
        if kn is None:
            continue
        xs, ys = kn[0], kn[1]
        for x0, x1, y0, y1 in zip(xs[:-1], xs[1:], ys[:-1], ys[1:], strict=True):
            if x1 > x0 and (y0 - 0.5) * (y1 - 0.5) <= 0 and y0 != y1:
                cands.append(np.array([x0 + (0.5 - y0) * (x1 - x0) / (y1 - y0)]))
    x = np.unique(np.concatenate(cands))
    x = x[(x >= low) & (x <= high)]
    dev = np.max(np.abs(np.stack([mf(x) for mf in terms]) - 0.5), axis=0)
    return float(x[np.flatnonzero(dev <= dev.min() + 1e-12)[0]])


def derived_min_rank(
    system: object, present: Iterable[str], *, edge_likelihood: float = EDGE_LIKELIHOOD
) -> float:
    """Lowest acceptable rank for a clue set, read off the rule base.

    The rank the system gives a detection at the edge of the acceptance region (likelihood
    ratio ``edge_likelihood``) when every other input present is at its neutral value
    (:func:`neutral_value`: no evidence either way). A pair is associated when its rank is at
    least this value: with neutral clues exactly the pairs with ``L >= edge_likelihood``;
    favourable clues admit pairs further out (up to the chi-square gate), unfavourable ones
    refuse pairs closer in.

    Parameters
    ----------
    system : FuzzySystem
        The rule base; must have an input ``likelihood``.
    present : iterable of str
        Inputs given to the system besides ``likelihood`` (names not in the system are
        ignored).
    edge_likelihood : float, optional
        ``L = exp(-d2 / 2)`` at the edge, in (0, 1] (default :data:`EDGE_LIKELIHOOD`, 0.25:
        ``d2`` = 2.77, inside which a true detection falls with probability 0.75).

    Returns
    -------
    float
        The rank, in the output universe.

    Examples
    --------
    >>> from fusion.active.rulebase import default_association_system
    >>> system = default_association_system()
    >>> round(derived_min_rank(system, []), 4)
    0.4405
    """
    if not 0.0 < edge_likelihood <= 1.0:
        raise ValueError(f"edge_likelihood must lie in (0, 1], got {edge_likelihood!r}")
    by_name = {v.name: v for v in system.variables}  # type: ignore[attr-defined]
    if "likelihood" not in by_name:
        raise ValueError("the fuzzy system has no input 'likelihood'")
    inputs = {"likelihood": np.array([float(edge_likelihood)])}
    for name in present:
        if name in by_name and name != "likelihood":
            inputs[name] = np.array([neutral_value(by_name[name])])
    return float(system.evaluate(inputs).crisp[0])  # type: ignore[attr-defined]


def assign(
    score: ArrayLike, valid: ArrayLike
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Pair rows with columns, at most once each, maximising the summed score of valid pairs.

    Parameters
    ----------
    score : array_like, shape (n_rows, n_cols)
        Pair scores (ranks or likelihood ratios), >= 0 where valid.
    valid : array_like of bool, shape (n_rows, n_cols)
        Pairs allowed.

    Returns
    -------
    rows, cols : ndarray of int
        The chosen pairs. When each row's best valid column is different, this is every row with
        its best column; otherwise the conflicts are settled by
        :func:`scipy.optimize.linear_sum_assignment`.
    """
    s = np.asarray(score, dtype=float)
    ok = np.asarray(valid, dtype=bool)
    if s.shape != ok.shape or s.ndim != 2:
        raise ValueError(f"score and valid must be 2-D of one shape, got {s.shape}, {ok.shape}")
    if s.size == 0 or not ok.any():
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    if np.any(s[ok] < 0):
        raise ValueError("scores of valid pairs must be >= 0")
    w = np.where(ok, s, -1.0)
    best = w.argmax(axis=1)
    has = ok[np.arange(s.shape[0]), best]
    if np.unique(best[has]).size == has.sum():       # no conflict: each row takes its best
        rows = np.flatnonzero(has)
        return rows.astype(np.int64), best[has].astype(np.int64)
    # Maximum-weight matching: invalid pairs weigh 0 and are dropped afterwards.
    r, c = linear_sum_assignment(np.where(ok, s, 0.0), maximize=True)
    keep = ok[r, c]
    return r[keep].astype(np.int64), c[keep].astype(np.int64)


def assign_by_priority(
    score: NDArray[np.float64], valid: NDArray[np.bool_], first: NDArray[np.bool_]
) -> NDArray[np.int64]:
    """Assign detections to tracks, the ``first`` tracks before the others.

    Parameters
    ----------
    score : ndarray, shape (n_tracks, n_detections)
        Pair scores (ranks or likelihood ratios), >= 0 where valid.
    valid : ndarray of bool, shape (n_tracks, n_detections)
        Pairs allowed.
    first : ndarray of bool, shape (n_tracks,)
        Tracks that choose first (the confirmed ones); the others share what is left.

    Returns
    -------
    ndarray of int, shape (n_tracks,)
        The detection of each track, -1 for none; each detection at most once (:func:`assign`
        within each group).
    """
    nt, nd = score.shape
    det_of = np.full(nt, -1, np.int64)
    taken = np.zeros(nd, dtype=bool)
    for group in (np.flatnonzero(first), np.flatnonzero(~first)):
        if group.size == 0:
            continue
        r, c = assign(score[group], valid[group] & ~taken[None, :])
        det_of[group[r]] = c
        taken[c] = True
    return det_of


class PairRanker:
    """Fuzzy rank of gated (track, detection) pairs and the lowest rank each may be associated at.

    Parameters
    ----------
    system : FuzzySystem
        Rule base with an input ``likelihood`` (e.g.
        :func:`fusion.active.rulebase.default_association_system`).
    clues : iterable of str, optional
        Which of :data:`CLUE_NAMES` may be used (default all); those absent from the data are left
        out anyway. ``aspect_deg`` covers both a given column and the angle computed from
        source/receiver positions.
    min_rank : float, optional
        Lowest rank that may be associated, the same for every pair, in [0, 1]. Default None:
        :func:`derived_min_rank` for the clues each pair actually has.
    edge_likelihood : float, optional
        Likelihood ratio at the edge of the acceptance region of the derived threshold, in
        (0, 1] (default :data:`EDGE_LIKELIHOOD`).
    confirmed_edge_likelihood : float, optional
        The same for pairs of confirmed tracks (default: `edge_likelihood`); lower lets a
        confirmed track keep a manoeuvring target whose detections fall further out.
    aspect : {"geometry", "measured"}, optional
        Where the equivalent aspect angle comes from. ``geometry`` (default): computed from the
        track's heading and the detection's source/receiver positions; an ``aspect_deg`` column
        is ignored. ``measured``: the ``aspect_deg`` column is a measurement and is used as it
        stands (geometry still serves pings without the column).

    Notes
    -----
    The aspect computed from geometry (:func:`fusion.active.bistatic.equivalent_aspect_deg`) is
    left out for tracks whose speed is not larger than its own standard deviation (heading
    unknown, e.g. a track born on the previous ping). The engine takes no missing values, so pairs
    with and without an aspect angle are ranked by two calls, each with its own threshold. An
    ``aspect_deg`` column is not used by default because nothing in a detection file says how it
    was obtained: a simulator may write the target's true aspect plus noise, which would hand the
    rank the very answer it is asked to find.
    """

    def __init__(
        self,
        system: object,
        *,
        clues: Iterable[str] | None = None,
        min_rank: float | None = None,
        edge_likelihood: float = EDGE_LIKELIHOOD,
        aspect: Literal["geometry", "measured"] = "geometry",
        confirmed_edge_likelihood: float | None = None,
    ) -> None:
        if aspect not in ("geometry", "measured"):
            raise ValueError(f"aspect must be 'geometry' or 'measured', got {aspect!r}")
        chosen = set(CLUE_NAMES if clues is None else clues)
        unknown = chosen - set(CLUE_NAMES)
        if unknown:
            raise ValueError(f"unknown clue(s) {', '.join(sorted(unknown))} "
                             f"(choose from {', '.join(CLUE_NAMES)})")
        if min_rank is not None and not 0.0 <= min_rank <= 1.0:
            raise ValueError(f"min_rank must lie in [0, 1], got {min_rank!r}")
        if not 0.0 < edge_likelihood <= 1.0:
            raise ValueError(f"edge_likelihood must lie in (0, 1], got {edge_likelihood!r}")
        if confirmed_edge_likelihood is not None and not 0.0 < confirmed_edge_likelihood <= 1.0:
            raise ValueError("confirmed_edge_likelihood must lie in (0, 1], got "
                             f"{confirmed_edge_likelihood!r}")
        self.system = system
        self.clues = frozenset(chosen)
        self.min_rank = None if min_rank is None else float(min_rank)
        self.edge_likelihood = float(edge_likelihood)
        self.confirmed_edge_likelihood = (self.edge_likelihood if confirmed_edge_likelihood is None
                                          else float(confirmed_edge_likelihood))
        self.aspect = aspect
        #: Derived thresholds by clue set (filled as clue sets are met), for tentative and for
        #: confirmed tracks.
        self.thresholds: dict[frozenset[str], float] = {}
        self.confirmed_thresholds: dict[frozenset[str], float] = {}

    def threshold(self, present: Iterable[str], *, confirmed: bool = False) -> float:
        """Lowest associable rank for pairs whose rank used the inputs ``present``.

        Parameters
        ----------
        present : iterable of str
            Inputs of the rank besides the likelihood.
        confirmed : bool, optional
            For a confirmed track: derived at ``confirmed_edge_likelihood`` instead.

        Returns
        -------
        float
            ``min_rank`` when given, else :func:`derived_min_rank` (cached per clue set).
        """
        if self.min_rank is not None:
            return self.min_rank
        key = frozenset(present)
        edge = self.confirmed_edge_likelihood if confirmed else self.edge_likelihood
        cache = self.confirmed_thresholds if confirmed else self.thresholds
        if key not in cache:
            cache[key] = derived_min_rank(self.system, key, edge_likelihood=edge)
            logger.info("rank threshold with clues {%s}%s: %.4f", ", ".join(sorted(key)),
                        " (confirmed tracks)" if confirmed else "", cache[key])
        return cache[key]

    def rank(
        self, ping: Ping, ti: NDArray[np.int64], di: NDArray[np.int64], L: NDArray[np.float64],
        hot_d: NDArray[np.float64], x: NDArray[np.float64], P: NDArray[np.float64],
        confirmed: NDArray[np.bool_] | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Fuzzy rank and rank threshold of the gated pairs ``(ti, di)``.

        Parameters
        ----------
        ping : Ping
            The detections (and their clues).
        ti, di : ndarray of int, shape (n_pairs,)
            Track and detection index of each pair.
        L : ndarray, shape (n_pairs,)
            Likelihood ratio ``exp(-d2 / 2)`` of each pair.
        hot_d : ndarray, shape (n_detections,)
            Distance of each detection to the nearest hotspot, m (inf without a clutter map).
        x : ndarray, shape (n_tracks, 4)
            Predicted track states (their velocities give the aspect angle).
        P : ndarray, shape (n_tracks, 4, 4)
            Predicted covariances.
        confirmed : ndarray of bool, shape (n_tracks,), optional
            Confirmed tracks: their pairs get the confirmed threshold.

        Returns
        -------
        rank, limit : ndarray, shape (n_pairs,)
            Rank of each pair and the threshold of its clue set (:meth:`threshold`).
        """
        conf = (np.zeros(ti.size, dtype=bool) if confirmed is None
                else np.asarray(confirmed, dtype=bool)[ti])
        inputs: dict[str, NDArray[np.float64]] = {"likelihood": L}
        for name in ("score", "snr_db"):
            if name in self.clues and name in ping.clues:
                inputs[name] = ping.clues[name][di]
        if "hotspot_distance_m" in self.clues:
            inputs["hotspot_distance_m"] = hot_d[di]
        aspect = None
        if "aspect_deg" in self.clues:
            if self.aspect == "measured" and "aspect_deg" in ping.clues:
                aspect = ping.clues["aspect_deg"][di]
            elif all(k in ping.clues for k in POSITION_CLUES):
                v = x[ti, 2:]
                pv = P[ti, 2:, 2:]
                known = np.sum(v * v, axis=1) > pv[:, 0, 0] + pv[:, 1, 1]
                src = np.column_stack([ping.clues["src_x"], ping.clues["src_y"]])[di]
                rcv = np.column_stack([ping.clues["rcv_x"], ping.clues["rcv_y"]])[di]
                aspect = equivalent_aspect_deg(ping.xy[di], v, src, rcv)
                aspect[~known] = np.nan
        others = set(inputs) - {"likelihood"}
        if aspect is None or not np.isnan(aspect).any():
            if aspect is not None:
                inputs["aspect_deg"] = aspect
                others.add("aspect_deg")
            rank = np.asarray(self.system.evaluate(inputs).crisp, dtype=float)
            return rank, np.where(conf, self.threshold(others, confirmed=True),
                                  self.threshold(others))
        # Pairs with and without an aspect angle use different rule subsets (the engine takes
        # no missing values), hence two calls; each gets the threshold of its own clue set.
        rank = np.empty(L.size)
        limit = np.empty(L.size)
        ok = ~np.isnan(aspect)
        for sel, with_aspect in ((ok, True), (~ok, False)):
            if not sel.any():
                continue
            part = {k: v[sel] for k, v in inputs.items()}
            if with_aspect:
                part["aspect_deg"] = aspect[sel]
            rank[sel] = self.system.evaluate(part).crisp
            used = others | ({"aspect_deg"} if with_aspect else set())
            limit[sel] = np.where(conf[sel], self.threshold(used, confirmed=True),
                                  self.threshold(used))
        return rank, limit
