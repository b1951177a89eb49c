"""Candidate solutions competing for a window's TDOAs (eq. 19-22 with an EM weight update).

K candidate positions share M TDOAs through weights ``w_km``, the probability that TDOA ``m``
belongs to candidate ``k`` (Baggenstoss 2011, as adopted by the localization text). They start
flat, ``w_km = 1/K`` (eq. 19), and each iteration alternates

(a) **candidate update** (eq. 20-22): at each candidate ``x_k`` the delay-fit weight
    ``beta_m = exp(-(d_m(x_k) - tau_m)^2 / (sigma_t^2/4))`` and the association weight
    ``gamma_km = sum_l (1 - exp(-alpha_ml/4)) beta_l beta_m`` (both evaluated at ``x_k``) give
    ``w~_km = w_km gamma_km``, written into the live weight array of the candidate's
    :func:`factors.tdoa.weighted_tdoa_vector_factor`; its one-factor graph is re-solved by
    Levenberg-Marquardt from ``x_k``;
(b) **weight update** (E-step of a mixture): each TDOA's responsibilities over the candidates,
    Gaussian in the delay residual, plus a clutter component of uniform density over the
    pair's physically possible delays ``|tau| <= |s_i - s_j|/c`` with a prior clutter fraction;
    the mixing proportions follow the responsibilities. Optionally a candidate keeps at most
    one TDOA's worth of weight per sensor pair (a source makes one delay per pair);
(c) **merge and drop**: two candidates whose predicted delays agree within ``merge_sigmas``
    (at the sharper one's scale) on the TDOAs they hold, or that, both annealed, split the
    same TDOAs between them, become one and pool their weights; once
    annealed, a candidate is dropped that holds too little (``sum_m w_km < min_weight``) or
    whose TDOAs of weight > 0.5 span fewer than ``min_independent`` independent sensor pairs
    (the rank of their incidence; 3 fix a 3-D position), counting with ``alpha`` only TDOAs
    associated with another of its TDOAs (:func:`supported_weights`: a ghost made of a few
    TDOAs of a source plus a clutter TDOA that happens to fit does not count the clutter one);
(d) **growth** (once converged): a candidate refits with the TDOAs left to clutter that are
    associated (``alpha >= min_alpha_link``) with its own, from where it is and (with a water
    column) from a few heights above and below; if all then fit within ``gate_sigmas`` it
    keeps them and the iterations resume. (A candidate that starts far from
    its source can settle on a subset of the source's TDOAs that fits a ghost position, the
    rest lost to clutter on the way; their association with the kept ones gives it away.)
(e) **echo ghosts** (after the last iteration): a survivor whose held delays are another
    survivor's moved by bottom-echo lags on at most two sensors, or read along its surface
    paths (a sign-inverted echo up to half a carrier period, ``polarity_slip_s``), is dropped,
    and so is one that hears a sensor only through its surface echo
    (``drop_echo_only_sensors``: the direct click is louder and earlier than its echo)
    (:mod:`fusion.localization.echo_ghosts`; ``echo_ghost_lag_s`` 0 switches it off).

The delay scale of (a) and (b) starts at the candidate grid's smoothing and shrinks by
``anneal_factor`` per iteration to the TDOA sigmas (a deterministic annealing: a candidate a
grid cell off its source sees its TDOAs' residuals of up to a few cell delays; with the TDOA
sigma at once every weight would vanish). Each candidate has its own scale, never smaller than
the largest delay change of its last move, so a candidate still travelling towards its source
does not lose that source's TDOAs to clutter on the way. ``sigma_t`` of eq. (20) is ``beta_scale`` times that
scale: with the text's factor 4 in the exponent, ``beta_scale = 4`` gives ``beta = 0.78`` at a
one-sigma residual and 0.1 at three.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (19)-(22) and paragraph [0047];
P. M. Baggenstoss, "An algorithm for the localization of multiple interfering sperm whales using
multi-sensor time difference of arrival", J. Acoust. Soc. Am. 130 (2011). The clutter component,
the mixing proportions, the per-pair cap, the annealing and the merge/drop rules are this
module's reading of that algorithm (the text gives no formulas for them).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray

from factors.tdoa import weighted_tdoa_vector_factor
from fusion.geometry import surface_image
from fusion.localization.competition_settings import CompetitionSettings
from fusion.localization.echo_ghosts import echo_ghosts, echo_only_sensors, surface_alternatives
from fusion.localization.ownership import (
    association_weights,
    cap_per_pair,
    holds_a_source,
    independent_pairs,
    pair_ids,
    same_source,
    supported_weights,
)
from fusion.localization.surface_paths import SEA_SURFACE_Z
from fusion.localization.window_tdoas import WindowTdoas

__all__ = [
    "CompetitionResult",
    "CompetitionSettings",
    "association_weights",
    "compete",
    "holds_a_source",
    "independent_pairs",
    "supported_weights",
    "vertical_starts",
]

_LOG = logging.getLogger(__name__)


@dataclass(frozen=True)
class CompetitionResult:
    """The surviving candidates of :func:`compete`.

    Attributes
    ----------
    positions : ndarray, shape (S, 3)
        Positions, m (from the last candidate update).
    weights : ndarray, shape (S, M)
        EM weights ``w_km`` (responsibilities) of the last weight update.
    combined : ndarray, shape (S, M)
        Weights ``w~_km = w_km gamma_km`` (eq. 22) of the last candidate update.
    clutter : ndarray, shape (M,)
        Weight left to clutter, ``1 - sum_k w_km`` (summed over the columns of the column's
        measurement when `groups` are given).
    origin : ndarray of int, shape (S,)
        Index of each survivor among the starting candidates.
    iterations : int
        Iterations run.
    converged : bool
        Whether the tolerance was met before ``max_iterations``.
    """

    positions: NDArray[np.float64]
    weights: NDArray[np.float64]
    combined: NDArray[np.float64]
    clutter: NDArray[np.float64]
    origin: NDArray[np.intp]
    iterations: int
    converged: bool


class _CandidateGraph:
    """The one-factor graph of the candidate updates, its TDOA weights written in place per solve."""

    def __init__(self, tdoas: WindowTdoas, iterations: int) -> None:
        self.key = gtsam.symbol("x", 0)
        self.weights = np.zeros(tdoas.m)
        self.factor = weighted_tdoa_vector_factor(
            gtsam.noiseModel.Diagonal.Sigmas(np.asarray(tdoas.sigmas)), self.key, tdoas.sensors,
            tdoas.pairs, tdoas.taus, self.weights, c=tdoas.c)
        self.graph = gtsam.NonlinearFactorGraph()
        self.graph.add(self.factor)
        self.params, self.params_long = gtsam.LevenbergMarquardtParams(), gtsam.LevenbergMarquardtParams()
        for params, limit in ((self.params, int(iterations)), (self.params_long, 100)):
            params.setMaxIterations(limit)
            params.setRelativeErrorTol(1e-10)
            params.setAbsoluteErrorTol(1e-20)

    def solve(self, x0: NDArray[np.float64], w: NDArray[np.float64], *, full: bool = False
              ) -> NDArray[np.float64]:
        """Weighted least-squares position from `x0` with weights `w` (eq. 22 update).

        `full` runs up to 100 Levenberg-Marquardt iterations instead of ``solver_iterations``.
        """
        self.weights[:] = w
        values = gtsam.Values()
        values.insert(self.key, gtsam.Point3(*x0))
        params = self.params_long if full else self.params
        result = gtsam.LevenbergMarquardtOptimizer(self.graph, values, params).optimize()
        return np.asarray(result.atPoint3(self.key), dtype=float)


def vertical_starts(x: NDArray, z_range: tuple[float, float] | None, levels: int = 4
                     ) -> list[NDArray]:
    """`x` and, with a water column, `x` moved to `levels` heights spread over it."""
    if z_range is None:
        return [x]
    z = z_range[0] + (np.arange(levels) + 0.5) / levels * (z_range[1] - z_range[0])
    return [x] + [np.array([x[0], x[1], zz]) for zz in z]


def _grow(
    tdoas: WindowTdoas, graph: _CandidateGraph, x: NDArray, w: NDArray, clutter: NDArray,
    cfg: CompetitionSettings, z_range: tuple[float, float] | None = None,
) -> tuple[NDArray, NDArray] | None:
    """Refit a candidate with the clutter TDOAs associated with its own; None if none fit.

    The refit starts from the candidate and, if that fails, with a water column, from its
    ``x, y`` at a few heights (a near-planar array's depth ambiguity); the fit explaining most
    TDOAs wins.
    """
    owned = w > 0.5
    if tdoas.alpha is None or not np.any(owned):
        return None
    linked = np.any(np.asarray(tdoas.alpha)[:, owned] >= cfg.min_alpha_link, axis=1)
    candidates_extra = linked & (clutter > 0.5) & ~owned
    if not np.any(candidates_extra):
        return None
    gate = cfg.gate_sigmas * np.asarray(tdoas.sigmas)
    best: tuple[int, float, NDArray, NDArray] | None = None
    for start in vertical_starts(x, z_range):
        if best is not None:
            break  # the other heights only when the candidate's own place fails
        extra = candidates_extra.copy()
        while np.any(extra):
            trial = (owned | extra).astype(float)  # hard: a half-held TDOA must not pull the fit
            new = graph.solve(start, trial, full=True)
            r = tdoas.predicted(new) - tdoas.taus
            fits = np.abs(r) <= gate
            if not np.all(fits[owned]):
                break
            if np.all(fits[extra]):
                cost = float(np.sum(trial * (r / np.asarray(tdoas.sigmas)) ** 2))
                if best is None or (int(trial.sum()), -cost) > (best[0], -best[1]):
                    best = (int(trial.sum()), cost, new, trial)
                break
            extra &= fits
    return None if best is None else (best[2], best[3])


def _group_total(v: NDArray[np.float64], group: NDArray[np.intp], n: int) -> NDArray[np.float64]:
    """Sum of `v` over the columns of each measurement, shape (n,)."""
    out = np.zeros(n)
    np.add.at(out, group, v)
    return out


def compete(
    tdoas: WindowTdoas,
    starts: ArrayLike,
    *,
    start_scale_s: float,
    settings: CompetitionSettings | None = None,
    z_range: tuple[float, float] | None = None,
    weights: ArrayLike | None = None,
    settled: ArrayLike | None = None,
    groups: ArrayLike | None = None,
    surface_z: float | None = None,
) -> CompetitionResult:
    """Let candidate positions compete for the TDOAs of one window.

    Parameters
    ----------
    tdoas : WindowTdoas
        The window's TDOAs (``alpha`` used when present and ``settings.use_alpha``).
    starts : array_like, shape (K, 3)
        Candidate positions, m (e.g. :class:`fusion.localization.candidates.CandidateFinder`).
    start_scale_s : float, keyword-only
        Delay uncertainty of the starts, s (e.g. the delay smoothing of the grid they come
        from); the annealing starts there.
    settings : CompetitionSettings, optional, keyword-only
        Options; default :class:`CompetitionSettings()`.
    z_range : (float, float), optional, keyword-only
        The water column ``(z_bottom, z_surface)``, m. A candidate that leaves it (by more than
        1 % of its height) is moved once to its mirror image through the sensors' best-fitting
        plane and re-annealed, if that image is in the water, and dropped otherwise (on a
        near-planar array a candidate started at the wrong depth can settle on the far side).
    weights : array_like, shape (K, M), optional, keyword-only
        Starting weights ``w_km`` in [0, 1] (a warm start); default flat ``1/K`` (eq. 19).
    settled : array_like of bool, shape (K,), optional, keyword-only
        Candidates that converged in an earlier round: their delay scale starts at the TDOA
        sigmas instead of `start_scale_s`.
    groups : array_like of int, shape (M,), optional, keyword-only
        The measurement each TDOA column reads (several columns: one measured delay read as
        several propagation paths, :mod:`fusion.localization.surface_paths`). The responsibilities of
        the columns of one measurement and its clutter component sum to one (a measured delay
        belongs to one candidate along one path, or to clutter). Default: every column its own
        measurement.
    surface_z : float, optional, keyword-only
        Height of the sea surface, m, when the columns include surface-reflected paths: a
        candidate above the surface explains the same delays as its image below it (direct and
        reflected paths swapped) and jumps there; the sensors' plane is then fitted to the
        sensors below the surface (the others are their images).

    Returns
    -------
    CompetitionResult
        The candidates that survived, in the order of `starts`.

    Notes
    -----
    Eq. (19)-(22) of *Localization of Short Duration Periodic Signals* with the weight update
    of Baggenstoss (2011) as described in the module docstring.
    """
    cfg = CompetitionSettings() if settings is None else settings
    x = np.array(starts, dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(x)):
        raise ValueError("candidate starts must be finite positions (K, 3)")
    if not (np.isfinite(start_scale_s) and start_scale_s > 0):
        raise ValueError(f"start_scale_s must be positive, got {start_scale_s!r}")
    m, k0 = tdoas.m, x.shape[0]
    sig = np.asarray(tdoas.sigmas)
    alpha = np.asarray(tdoas.alpha) if cfg.use_alpha and tdoas.alpha is not None else None
    pairs = np.asarray(tdoas.pairs)
    pair_id = pair_ids(pairs)
    group = np.arange(m) if groups is None else np.asarray(groups, dtype=np.intp).reshape(-1)
    if group.shape != (m,) or group.min(initial=0) < 0:
        raise ValueError(f"groups must hold one non-negative measurement index per TDOA ({m})")
    n_groups = int(group.max(initial=-1)) + 1
    # uniform clutter density over the physically possible delays of each pair
    log_clutter_col = (np.log(cfg.clutter_fraction)
                       - np.log(2.0 * np.maximum(tdoas.max_delay_s, sig)))
    log_clutter = np.full(n_groups, -np.inf)  # per measurement: its narrowest pair's density
    np.maximum.at(log_clutter, group, log_clutter_col)
    w = np.full((k0, m), 1.0 / max(k0, 1))  # eq. (19)
    if weights is not None:  # a warm start (a later round)
        w = np.array(weights, dtype=float)
        if w.shape != (k0, m) or not np.all((w >= 0) & (w <= 1)):
            raise ValueError(f"weights must have shape ({k0}, {m}) with values in [0, 1]")
    wt = np.zeros((k0, m))
    totals = w.sum(axis=1) + 1e-12
    log_pi = np.log((1.0 - cfg.clutter_fraction) * totals / totals.sum())
    alive = np.ones(k0, dtype=bool)
    # one graph serves every candidate: each solve writes all its weights and starts afresh
    graph = _CandidateGraph(tdoas, cfg.solver_iterations)
    # per-candidate delay scale: shrinks by anneal_factor per iteration, but never below the
    # delay change of the candidate's last move (a travelling candidate keeps its TDOAs)
    spread0 = max(float(start_scale_s), float(sig.max()))
    spread = np.full(k0, spread0)
    if settled is not None:  # candidates already at their TDOA sigma level
        spread[np.asarray(settled, dtype=bool)] = float(sig.min())
    mirrored = np.zeros(k0, dtype=bool)
    real = np.asarray(tdoas.sensors)
    if surface_z is not None:  # the sensors below the surface (the rest are their images)
        real = real[real[:, 2] < surface_z]
    centre = real.mean(axis=0)
    normal = np.linalg.svd(real - centre)[2][-1]  # of the best-fit plane
    tol_m = cfg.tol * float(sig.min()) * tdoas.c
    z_margin = 0.01 * (z_range[1] - z_range[0]) if z_range is not None else 0.0
    converged, it, grow_passes = False, 0, 2
    for it in range(1, cfg.max_iterations + 1):
        idx = np.flatnonzero(alive)
        if idx.size == 0:
            break
        scale = np.maximum(sig[None, :], spread[idx, None])  # (K', M), s
        # (a) candidate update, eq. (20)-(22)
        r = tdoas.predicted(x[idx]) - tdoas.taus  # d_m(x_k) - tau_m, (K', M)
        _, gamma = association_weights(r, cfg.beta_scale * scale, alpha)
        wt[idx] = w[idx] * gamma  # eq. (22)
        moved = 0.0
        for row, k in enumerate(idx):
            strong = wt[k] > 1e-6 * max(float(wt[k].max()), 1e-300)
            step_s = 0.0
            if independent_pairs(pairs, strong) >= 3:  # else too little to fix a position
                new = graph.solve(x[k], wt[k])
                moved = max(moved, float(np.linalg.norm(new - x[k])))
                step_s = float(np.max(np.abs(tdoas.predicted(new) - r[row] - tdoas.taus)))
                x[k] = new
            spread[k] = max(spread[k] * cfg.anneal_factor, step_s)
        annealed = bool(np.all(spread[idx] <= sig.min()))
        scale = np.maximum(sig[None, :], spread[idx, None])
        # a candidate that left the water column (e.g. below the sea floor) sits on the wrong
        # side of the sensors' plane: it jumps to its mirror image once, else it is dropped
        if z_range is not None:
            for k in idx:
                if z_range[0] - z_margin <= x[k, 2] <= z_range[1] + z_margin:
                    continue
                image = x[k] - 2.0 * float((x[k] - centre) @ normal) * normal
                if surface_z is not None and x[k, 2] > surface_z:  # its surface image
                    image = surface_image(x[k], surface_z)
                if not mirrored[k] and z_range[0] <= image[2] <= z_range[1]:
                    _LOG.debug("iteration %d: candidate %d (z = %.1f m) to its mirror image", it,
                               k, x[k, 2])
                    x[k], spread[k], mirrored[k] = image, spread0, True
                else:
                    alive[k] = False
                    _LOG.debug("iteration %d: candidate %d dropped (z = %.1f m)", it, k, x[k, 2])
            idx = np.flatnonzero(alive)
            if idx.size == 0:
                break
            scale = np.maximum(sig[None, :], spread[idx, None])
        # (b) weight update: responsibilities with a uniform clutter component
        delays = tdoas.predicted(x[idx])  # (K', M), also read by the merge below
        r = delays - tdoas.taus
        loglik = log_pi[idx, None] - 0.5 * (r / scale) ** 2 - np.log(np.sqrt(2 * np.pi) * scale)
        # normalised over the candidates, the columns of one measurement and clutter
        top = log_clutter.copy()
        np.maximum.at(top, group, loglik.max(axis=0))
        resp = np.exp(loglik - top[group])
        total = np.exp(log_clutter - top)
        np.add.at(total, group, resp.sum(axis=0))
        resp = resp / total[group]
        if cfg.pair_exclusive:
            resp = cap_per_pair(resp, pair_id)
        change = float(np.abs(resp - w[idx]).max())
        w[idx] = resp
        totals = resp.sum(axis=1)
        if totals.sum() > 0:
            log_pi[idx] = np.log((1.0 - cfg.clutter_fraction) * np.maximum(totals, 1e-300)
                                 / totals.sum())
        # (c) merge candidates explaining the same TDOAs (the one holding more survives)
        for pa, a in enumerate(idx):
            for pb in range(pa + 1, idx.size):
                b = idx[pb]
                if not (alive[a] and alive[b]):
                    continue
                if same_source(tdoas, x[a], x[b], w[a], w[b],
                                np.minimum(scale[pa], scale[pb]), cfg,
                                settled=bool(max(spread[a], spread[b]) <= sig.min()),
                                delays=(delays[pa], delays[pb])):
                    loser = b if w[a].sum() >= w[b].sum() else a
                    alive[loser] = False
                    w[a + b - loser] = np.minimum(w[a] + w[b], 1.0)  # joined: the TDOAs of both
                    _LOG.debug("iteration %d: candidate %d merged into %d", it, loser, a + b - loser)
        # ... and drop those holding too little (fully once annealed)
        for k in np.flatnonzero(alive):
            if spread[k] > sig.min():  # still annealing: only the empty ones go
                if w[k].sum() < min(0.25, cfg.min_weight):
                    alive[k] = False
                    _LOG.debug("iteration %d: candidate %d dropped (weight %.2f)", it, k,
                               w[k].sum())
            elif not holds_a_source(w[k], pairs, alpha, cfg):
                alive[k] = False
                _LOG.debug("iteration %d: candidate %d dropped (weight %.2f, supported %.2f)", it,
                           k, w[k].sum(), supported_weights(w[k], alpha, cfg.min_alpha_link).sum())
        if annealed and moved < tol_m and change < cfg.tol:
            # growth: a candidate that settled on a subset of its source's TDOAs (the others
            # lost to clutter on the way) refits with the associated clutter TDOAs
            grew = False
            if grow_passes:
                left = 1.0 - _group_total(w[alive].sum(axis=0), group, n_groups)[group]
                for k in np.flatnonzero(alive):
                    out = _grow(tdoas, graph, x[k], w[k], left, cfg, z_range)
                    if out is not None:
                        x[k], w[k] = out
                        grew = True
                        _LOG.debug("iteration %d: candidate %d grew", it, k)
                grow_passes -= 1
            if not grew:
                converged = True
                break
    idx = np.flatnonzero(alive)
    if cfg.echo_ghost_lag_s > 0 and idx.size > 1:  # (e) candidates made of echoes of another
        sea = surface_z if surface_z is not None else (
            SEA_SURFACE_Z if np.all(np.asarray(tdoas.sensors)[:, 2] < SEA_SURFACE_Z) else None)
        alt = ({} if sea is None else dict(zip(
            ("reflected", "reflected_pairs", "inverted", "image_keys"),
            surface_alternatives(x[idx], tdoas.sensors, pairs, tdoas.c, sea), strict=True)))
        ghost = echo_ghosts(tdoas.taus, sig, pairs, tdoas.predicted(x[idx]), w[idx] > 0.5,
                            max_lag_s=cfg.echo_ghost_lag_s, slip_s=cfg.polarity_slip_s, **alt)
        if np.any(ghost):
            _LOG.debug("competition: %d echo ghosts dropped", int(ghost.sum()))
            idx = idx[~ghost]
    if cfg.drop_echo_only_sensors and surface_z is not None and idx.size:
        alias = echo_only_sensors(tdoas.sensors, pairs, w[idx] > 0.5, surface_z)
        if np.any(alias):
            _LOG.debug("competition: %d candidates hearing a sensor only by its echo dropped",
                       int(alias.sum()))
            idx = idx[~alias]
    clutter = (1.0 - _group_total(w[idx].sum(axis=0), group, n_groups)[group] if idx.size
               else np.ones(m))
    _LOG.debug("competition: %d of %d candidates survive after %d iterations (converged %s)",
               idx.size, k0, it, converged)
    return CompetitionResult(positions=x[idx], weights=w[idx], combined=wt[idx],
                             clutter=np.clip(clutter, 0.0, 1.0), origin=idx, iterations=it,
                             converged=converged)
