"""Judging pairs on the window ladder (:func:`ladder_hits`) and on one window of it: the
crossing time, its interval with the allowances (curvature, manoeuvre, far end), whether the
window resolves the pair, and the direction (a part of
:class:`~fusion.passive.crossing.detector.CrossingDetector`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.passive.crossing.curvature import CurvatureStats
from fusion.passive.crossing.curve import CurveStats, curved_candidates, curved_pair_intervals
from fusion.passive.crossing.events import _Hits
from fusion.passive.crossing.interval import f_ratio_quantile, t_quantile
from fusion.passive.crossing.manoeuvre import manoeuvre_variance
from fusion.passive.crossing.pairs import pair_intervals, pairs_in_reach
from fusion.passive.line_fit import LineStats

__all__ = ["CURVE_ALLOWANCE_REACHES", "judge_pairs", "ladder_hits"]

#: A curved pair's interval widened by the manoeuvre allowance is looked for up to this many
#: reaches ahead (its grid grows to match); an upper end beyond it is reported as that limit.
CURVE_ALLOWANCE_REACHES = 2.0


def judge_pairs(
    det: Any, model: tuple[LineStats, CurveStats | None, CurvatureStats | None],
    ia: NDArray[np.int64], ib: NDArray[np.int64], *, back_s: float, reach_s: float,
    span_s: float, only_resolved: bool = False,
) -> tuple[NDArray[np.float64], ...]:
    """Crossing time, interval, resolved flag, direction and confirming interval of pairs on
    one window.

    `det` is the :class:`~fusion.passive.crossing.detector.CrossingDetector` (its level,
    allowances and limits); `model` the window's line, curve and curvature statistics. The
    confirming interval (``conf_low``, ``conf_high``) is the reported one except for pairs on
    curves widened by the manoeuvre allowance (`det.curve_manoeuvre`): for them it is the
    curves' own, so the allowance only widens what is reported (below the gate level).
    `only_resolved`: only the resolved flag is wanted, the other values of pairs not resolved
    may be NaN (pairs on lines whose lines' own interval is already too wide skip the
    allowances: ``max_width_s`` of :func:`~fusion.passive.crossing.pairs.pair_intervals`).
    """
    st, cs, qs = model
    man = None if det.manoeuvre_q is None else (det.manoeuvre_q, span_s)
    gates = det.allowance_gate_level is not None and \
        span_s >= (1 << det.allowance_gate_level) * det.J * det.K * (1 - 1e-9)
    prune = det.max_interval_s if only_resolved else None
    # only the verdict wanted below the gate: it comes from the intervals without the
    # allowances, which only widen -- so they are not computed (the same verdicts)
    verdict_only = only_resolved and not gates and det.extrapolation_scale <= 1.0
    if verdict_only:
        man_p, far_p = None, False
    else:
        man_p, far_p = man, det.far_side
    # below the gate resolved as without the allowances, which only widen (`gate_width`)
    tau, low, high, ok, *gate = pair_intervals(
        ia, ib, st.value, st, level=det.level, curvature=qs, manoeuvre=man_p,
        far_side=far_p, own_width=not gates and (man_p is not None or far_p),
        max_width_s=prune)
    gate_width = gate[0] if gate else None
    k = det.extrapolation_scale
    if k > 1.0:  # predictions: the lines' extrapolation variance grown by k
        _, lk, hk, okk = pair_intervals(ia, ib, st.value, st, level=det.level, var_scale=k,
                                        curvature=qs, manoeuvre=man,
                                        far_side=det.far_side, max_width_s=prune)
        ahead = tau > 0
        low, high, ok = (np.where(ahead, x, y) for x, y in ((lk, low), (hk, high), (okk, ok)))
    direction = np.sign(st.slope[ib] - st.slope[ia])
    conf_low, conf_high = low, high
    if cs is not None:
        c = np.flatnonzero(cs.curved[ia] | cs.curved[ib])
        if c.size:
            q = t_quantile(det.level, np.minimum(cs.dof[ia[c]], cs.dof[ib[c]]))
            tc, lc, hc, okc, dc = curved_pair_intervals(
                ia[c], ib[c], cs, q=q, back_s=back_s, reach_s=reach_s,
                ahead_var_scale=k)
            lc0, hc0 = lc, hc
            if man is not None and det.curve_manoeuvre and not verdict_only:  # rate wander too
                qc = (man[0][ia[c]] + man[0][ib[c]])[:, None]
                ext = CURVE_ALLOWANCE_REACHES * reach_s
                _, lw, hw, okw, _ = curved_pair_intervals(
                    ia[c], ib[c], cs, q=q, back_s=back_s, reach_s=ext, ahead_var_scale=k,
                    n_grid=129 + int(np.ceil(128 * (ext - reach_s) / (reach_s + back_s))),
                    ahead_var=lambda tt: manoeuvre_variance(qc, span_s, tt))
                # below the gate resolved as without it (it only widens; an upper end beyond
                # the grid is reported as the grid's end: the variance behind the sample is
                # unchanged, so only that end can run off); from the gate on it also resolves
                lc = np.where(okc, np.where(np.isfinite(lw), np.minimum(lw, lc), lc), lc)
                hc = np.where(okc, np.where(okw, np.maximum(hw, hc), ext), hc)
                if gates:
                    okc = okc & okw
            tau, low, high, ok, direction = (x.copy() for x in (tau, low, high, ok, direction))
            conf_low, conf_high = low.copy(), high.copy()
            conf_low[c], conf_high[c] = lc0, hc0
            tau[c], low[c], high[c], ok[c], direction[c] = tc, lc, hc, okc, dc
            if gate_width is not None:
                gate_width = gate_width.copy()
                gate_width[c] = hc0 - lc0
    with np.errstate(invalid="ignore"):
        ok &= ((high - low) if gate_width is None else gate_width) <= det.max_interval_s
    return tau, low, high, ok, direction, conf_low, conf_high


#: Most tracks for which a window's verdicts are kept in a dense table (n^2 bytes) rather than
#: in sorted keys.
_DENSE_TRACKS = 4096


class _Judged:
    """Which pairs (keys ``a * n + b`` of positions among `n` tracks) one window of the ladder
    resolved at this sample, so a pair checked there for a longer window is judged there once
    (a table of ``n^2`` bytes, 0 unknown, 1 resolved, 2 not; sorted keys for many tracks)."""

    def __init__(self, n: int) -> None:
        self.dense = np.zeros(n * n, np.int8) if n <= _DENSE_TRACKS else None
        self.key = np.zeros(0, np.int64)
        self.ok = np.zeros(0, bool)

    def add(self, key: NDArray[np.int64], ok: NDArray[np.bool_]) -> None:
        if self.dense is not None:
            self.dense[key] = np.where(ok, 1, 2)
            return
        k = np.concatenate([self.key, key])
        order = np.argsort(k, kind="stable")
        self.key, self.ok = k[order], np.concatenate([self.ok, ok])[order]

    def find(self, key: NDArray[np.int64]) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """(known, resolved) of `key`."""
        if self.dense is not None:
            v = self.dense[key]
            return v > 0, v == 1
        if self.key.size == 0:
            return np.zeros(key.size, bool), np.zeros(key.size, bool)
        pos = np.minimum(np.searchsorted(self.key, key), self.key.size - 1)
        known = self.key[pos] == key
        return known, known & self.ok[pos]


def ladder_hits(det: Any, t: float, ids: NDArray[np.int64]) -> _Hits:
    """Pairs satisfying an inequality on the shortest window that resolves them.

    `det` is the :class:`~fusion.passive.crossing.detector.CrossingDetector` (its fits already
    updated with the sample at `t`); `ids` the tracks of the sample, sorted. Each window of the
    ladder lists the pairs in its reach; a pair is judged on the shorter windows first (the
    longest first: fewest left) and on its own only if none of them resolves it. A pair's
    verdict on a window is kept for the sample (:class:`_Judged`), so a pair in the reach of
    several windows is judged on each shorter window once.
    """
    parts: list[tuple] = []
    models: list[tuple[LineStats, CurveStats | None, CurvatureStats | None]] = []
    reach: list[tuple[float, float]] = []
    judged: list[_Judged] = []
    admitted = np.ones(ids.size, bool)  # tracks whose longer windows fit as well
    var_prev = dof_prev = np.zeros(ids.size)
    n = ids.size
    need = det.window_need
    for level, (fit, J) in enumerate(zip(det.fits, det.windows, strict=True)):
        model = det._models(fit, ids, t, curves=level < det.curve_windows)
        st, cs, _ = model
        models.append(model)
        judged.append(_Judged(n))
        var = st.residual_var if cs is None else cs.residual_var
        dof = st.n - 2.0 if cs is None else cs.dof
        use = st.n >= need[level]  # full, or filled beyond `window_fill` (longer windows)
        if level > 0 and det.ladder_alpha is not None:  # it must fit as well as the last
            with np.errstate(invalid="ignore"):
                admitted &= ~(var > f_ratio_quantile(det.ladder_alpha, dof, dof_prev) * var_prev)
            use &= admitted
        var_prev, dof_prev = var, dof
        sel = np.flatnonzero(use)
        if sel.size < 2:
            break
        span = J * det.K
        lead = min(det.horizon_s, det.confirm_lead * span)  # alerts: lead_windows
        back = min(span, det.horizon_s, det.lead_windows * span)
        reach.append((back, lead))
        ia, ib, tau = pairs_in_reach(st.value[sel], st.slope[sel], reach_s=lead,
                                     min_rate_diff_rad_per_s=det.min_rate_diff_rad_per_s)
        if cs is not None and np.any(cs.curved[sel]):
            ca, cb = curved_candidates(cs.subset(sel), reach_s=max(lead, back))
            key = np.unique(np.concatenate([ia * sel.size + ib, ca * sel.size + cb]))
            ia, ib = key // sel.size, key % sel.size
        ia, ib = sel[ia], sel[ib]  # positions among `ids`
        if det.level is None:
            low = high = np.full(tau.size, np.nan)
            ok = np.ones(tau.size, bool)
            direction = np.sign(st.slope[ib] - st.slope[ia])
            conf = [low, high]
        else:
            k = np.arange(ia.size)
            for lower in range(level - 1, -1, -1):
                key = ia[k] * n + ib[k]
                known, res = judged[lower].find(key)
                new = np.flatnonzero(~known)
                if new.size:
                    r = judge_pairs(det, models[lower], ia[k[new]], ib[k[new]],
                                    back_s=reach[lower][0], reach_s=reach[lower][1],
                                    span_s=det.windows[lower] * det.K, only_resolved=True)[3]
                    judged[lower].add(key[new], r)
                    res[new] = r
                k = k[~res]
            ia, ib = ia[k], ib[k]
            tau, low, high, ok, direction, *conf = judge_pairs(
                det, model, ia, ib, back_s=back, reach_s=lead, span_s=span)
            if level + 1 < len(det.windows):  # the longest window is never asked again
                judged[level].add(ia * n + ib, ok)
        with np.errstate(invalid="ignore"):
            pred = ok & (tau > 0.0) & (tau <= lead)  # inequality (3)
            hit = ok & (tau >= -back) & (tau <= 0.0)  # inequality (4)
        k = np.flatnonzero(pred | hit)
        parts.append((ids[ia[k]], ids[ib[k]], t + tau[k], t + low[k], t + high[k], pred[k],
                      np.full(k.size, span), direction[k], t + conf[0][k], t + conf[1][k]))
    if not parts:
        z = np.zeros(0)
        return _Hits(np.zeros(0, np.int64), np.zeros(0, np.int64), z, z, z, np.zeros(0, bool),
                     z, z, z, z)
    cols = [np.concatenate(c) for c in zip(*parts, strict=True)]
    srt = np.lexsort((cols[1], cols[0]))
    return _Hits(*(c[srt] for c in cols))
