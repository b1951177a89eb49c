"""The curvature a window's line leaves out, as extrapolation variance of a predicted crossing.

A straight line fitted over a bearing window (routine 104A of *Target Track Crossing
Prediction/Detection*) is extrapolated to predict a crossing. Where the bearing curves (a
vessel passing close to the sensor, or turning) the line's own covariance says nothing about
the curvature, which the F-test of :func:`~fusion.passive.crossing.curve.curve_fits` found too
weak to fit a curve for: the extrapolated line then misses by ``c g(tau)``, with ``c`` the
bearing's second-order coefficient and ``g(tau) = tau^2 - (alpha + beta tau)`` what the line
fitted to ``t^2`` over the window misses at ``tau``. This module estimates ``c`` from each
window's line residuals (the quadratic term of the window's least squares, ``c = <r, h> /
<h, h>`` with ``h`` the residual of ``t^2`` on the line's regressors) and its variance
``s^2 / <h, h>``, and turns them into the variance a pair's difference line misses at its
predicted crossing (:func:`curvature_variance`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from fusion.passive.line_fit import LineStats

__all__ = ["CurvatureStats", "curvature_stats", "curvature_variance"]


@dataclass(frozen=True)
class CurvatureStats:
    """Second-order terms of window lines (times from the current sample, s).

    Attributes
    ----------
    c : ndarray, shape (n,)
        Least-squares coefficient of ``t^2`` over the window, rad/s^2 (0 for windows of fewer
        than 4 samples).
    var_c : ndarray, shape (n,)
        Its variance, with the line's residual variance as the noise.
    alpha, beta : ndarray, shape (n,)
        The line ``alpha + beta t`` fitted to ``t^2`` over the window (``g(tau) = tau^2 -
        alpha - beta tau``).
    """

    c: NDArray[np.float64]
    var_c: NDArray[np.float64]
    alpha: NDArray[np.float64]
    beta: NDArray[np.float64]

    def g(self, index: NDArray[np.int64], tau: NDArray[np.float64]) -> NDArray[np.float64]:
        """What the line of ``t^2`` over window `index` misses at `tau` (s^2)."""
        return tau * tau - self.alpha[index] - self.beta[index] * tau


def curvature_stats(
    tau: NDArray[np.float64], value: NDArray[np.float64], valid: NDArray[np.bool_],
    line: LineStats,
) -> CurvatureStats:
    """The quadratic term of each window beyond its line.

    Parameters
    ----------
    tau, value, valid, line
        The windows and their lines, as in :func:`~fusion.passive.crossing.curve.curve_fits`.

    Returns
    -------
    CurvatureStats

    Notes
    -----
    With ``h_k = t_k^2 - (alpha + beta t_k)`` the residual of ``t^2`` on ``[1, t]`` over the
    window, the quadratic fit's coefficient is ``c = sum r_k h_k / sum h_k^2`` (``r`` the line's
    residuals, Frisch-Waugh-Lovell) and ``var c = s^2 / sum h_k^2``. ``s^2`` is the line's
    residual variance (it holds the curvature too: the variance errs wide).
    """
    # windows hold 0 in `tau` and `value` where `valid` is False: plain row sums are the
    # window's sums. h is orthogonal to 1 and t, so <r, h> = <value, h> and <h, h> = <t^2, h>.
    n = valid.sum(axis=1).astype(float)
    t2 = tau * tau
    s1, s2 = tau.sum(axis=1), t2.sum(axis=1)
    s3 = np.einsum("ij,ij->i", t2, tau)
    s4 = np.einsum("ij,ij->i", t2, t2)
    y0 = value.sum(axis=1)
    y1 = np.einsum("ij,ij->i", tau, value)
    y2 = np.einsum("ij,ij->i", t2, value)
    with np.errstate(invalid="ignore", divide="ignore"):
        nn = np.maximum(n, 1.0)
        stt = s2 - s1 * s1 / nn
        beta = np.where(stt > 0, (s3 - s1 * s2 / nn) / np.where(stt > 0, stt, 1.0), 0.0)
        alpha = (s2 - beta * s1) / nn
        hh = s4 - alpha * s2 - beta * s3
        good = (n >= 4) & (hh > 0)
        hh1 = np.where(good, hh, 1.0)
        c = np.where(good, (y2 - alpha * y0 - beta * y1) / hh1, 0.0)
        var_c = np.where(good, np.nan_to_num(line.residual_var, nan=0.0) / hh1, 0.0)
    return CurvatureStats(c=c, var_c=var_c, alpha=alpha, beta=beta)


def curvature_variance(
    cs: CurvatureStats, index_a: NDArray[np.int64], index_b: NDArray[np.int64],
    tau: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Mean squared miss of the pairs' difference line at `tau` from the curvature left out.

    ``(c_b g_b - c_a g_a)^2 + var c_a g_a^2 + var c_b g_b^2`` at `tau` (rad^2; the estimate's
    square plus its variance: the expected square of the true term errs wide). 0 where `tau`
    is not finite.
    """
    t = np.where(np.isfinite(tau), tau, 0.0)
    ga, gb = cs.g(index_a, t), cs.g(index_b, t)
    e = (cs.c[index_b] * gb - cs.c[index_a] * ga) ** 2 \
        + cs.var_c[index_a] * ga * ga + cs.var_c[index_b] * gb * gb
    return np.where(np.isfinite(tau), e, 0.0)
