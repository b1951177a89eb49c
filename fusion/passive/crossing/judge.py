"""Judging pairs on one window of the ladder: the crossing time, its interval with the
allowances (curvature, manoeuvre, far end), whether the window resolves the pair, and the
direction (a part of :class:`~fusion.passive.crossing.detector.CrossingDetector`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.passive.crossing.curvature import CurvatureStats
from fusion.passive.crossing.curve import CurveStats, curved_pair_intervals
from fusion.passive.crossing.interval import t_quantile
from fusion.passive.crossing.manoeuvre import manoeuvre_variance
from fusion.passive.crossing.pairs import pair_intervals
from fusion.passive.line_fit import LineStats

__all__ = ["CURVE_ALLOWANCE_REACHES", "judge_pairs"]

#: A curved pair's interval widened by the manoeuvre allowance is looked for up to this many
#: reaches ahead (its grid grows to match); an upper end beyond it is reported as that limit.
CURVE_ALLOWANCE_REACHES = 2.0


def judge_pairs(
    det: Any, model: tuple[LineStats, CurveStats | None, CurvatureStats | None],
    ia: NDArray[np.int64], ib: NDArray[np.int64], *, back_s: float, reach_s: float,
    span_s: float,
) -> tuple[NDArray[np.float64], ...]:
    """Crossing time, interval, resolved flag, direction and confirming interval of pairs on
    one window.

    `det` is the :class:`~fusion.passive.crossing.detector.CrossingDetector` (its level,
    allowances and limits); `model` the window's line, curve and curvature statistics. The
    confirming interval (``conf_low``, ``conf_high``) is the reported one except for pairs on
    curves widened by the manoeuvre allowance (`det.curve_manoeuvre`): for them it is the
    curves' own, so the allowance only widens what is reported (below the gate level).
    """
    st, cs, qs = model
    man = None if det.manoeuvre_q is None else (det.manoeuvre_q, span_s)
    tau, low, high, ok = pair_intervals(ia, ib, st.value, st, level=det.level, curvature=qs,
                                        manoeuvre=man, far_side=det.far_side)
    gate_width = None
    gates = det.allowance_gate_level is not None and \
        span_s >= (1 << det.allowance_gate_level) * det.J * det.K * (1 - 1e-9)
    if not gates and (man is not None or det.far_side):
        _, bl, bh, _ = pair_intervals(ia, ib, st.value, st, level=det.level, curvature=qs)
        gate_width = bh - bl  # resolved as without the allowances, which only widen
    k = det.extrapolation_scale
    if k > 1.0:  # predictions: the lines' extrapolation variance grown by k
        _, lk, hk, okk = pair_intervals(ia, ib, st.value, st, level=det.level, var_scale=k,
                                        curvature=qs, manoeuvre=man,
                                        far_side=det.far_side)
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
            if man is not None and det.curve_manoeuvre:  # the curves' rate wander too
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
