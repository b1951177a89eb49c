"""Centroid defuzzification of the union of cut output sets, exact for piecewise-linear sets.

Section 6 of "Target tracking using fuzzy logic association" ("Combining rules"): the crisp
output is the centroid of ``max_k min(alpha_k, mu_k(y))`` over the output universe.

The centroid is computed EXACTLY (up to rounding) when every output term is piecewise linear
(triangular, trapezoidal, shoulders, vertical edges included). With at most six output terms it
uses the maximum-minimums identity
``max_k a_k = sum over non-empty subsets S of (-1)^(|S|+1) min_{k in S} a_k``: with
``a_k = min(alpha_k, mu_k(y))``, each subset term is one fixed piecewise-linear set
(``min_{k in S} mu_k``, precomputed between the terms' knots and crossings) cut at one level
(``min_{k in S} alpha_k``), whose area and first moment are closed-form sums over its linear
pieces. With more terms, the union is integrated between all of its breakpoints (knots, term
crossings and the points where a sloped segment reaches a cut level), on each of which it is
linear. If any output term is smooth (Gaussian, sigmoid), two-point Gauss-Legendre quadrature is
applied on a uniform grid of ``quad_segments`` pieces refined by those breakpoints; with the
default 2048 pieces the tests and the benchmark find the centroid within 1e-6 of the output
range of a 10^6-point trapezoid rule.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from fusion.active.fuzzy.variables import LinguisticVariable

__all__ = ["MAX_TERMS_INCLUSION_EXCLUSION", "Centroid"]

# Two-point Gauss-Legendre nodes on [0, 1]: exact for cubics, so exact for the
# area (linear) and moment (quadratic) of a linear piece.
_GL_LO = 0.5 - 0.5 / math.sqrt(3.0)
_GL_HI = 0.5 + 0.5 / math.sqrt(3.0)
# Output variables with at most this many piecewise-linear terms use the
# maximum-minimums identity (2^K - 1 subsets); more terms use breakpoints.
MAX_TERMS_INCLUSION_EXCLUSION = 6


class Centroid:
    """Centroid of ``max_k min(alpha_k, mu_k(y))`` over a universe, vectorised.

    Exact when every term is piecewise linear (see the module docstring);
    otherwise two-point Gauss-Legendre on a fine uniform grid refined by the
    linear terms' breakpoints.
    """

    def __init__(self, output: LinguisticVariable, *, quad_segments: int) -> None:
        low, high = output.universe
        self.low, self.high = low, high
        self.mfs = tuple(output.terms.values())
        static: list[float] = [low, high]
        lines: list[tuple[int, float, float, float, float]] = []  # term, x0, x1, y0, y1
        self.exact = True
        for k, mf in enumerate(self.mfs):
            pl = mf.knots()
            if pl is None:
                self.exact = False
                continue
            xs, ys, left, right = pl
            xs_ext = np.concatenate([[min(low, xs[0])], xs, [max(high, xs[-1])]])
            ys_ext = np.concatenate([[left], ys, [right]])
            for x0, x1, y0, y1 in zip(xs_ext[:-1], xs_ext[1:], ys_ext[:-1], ys_ext[1:], strict=True):
                if min(x1, high) <= max(x0, low):
                    continue  # vertical edge or outside the universe
                static.extend([max(x0, low), min(x1, high)])
                lines.append((k, float(x0), float(x1), float(y0), float(y1)))
        # Crossings of segment lines of different terms: fixed breakpoints.
        for i, (k1, a0, a1, p0, p1) in enumerate(lines):
            s1 = (p1 - p0) / (a1 - a0)
            for k2, b0, b1, q0, q1 in lines[i + 1:]:
                s2 = (q1 - q0) / (b1 - b0)
                if k2 == k1 or s1 == s2:
                    continue
                x = (q0 - p0 + s1 * a0 - s2 * b0) / (s1 - s2)  # p0 + s1 (x - a0) = q0 + s2 (x - b0)
                if max(a0, b0, low) <= x <= min(a1, b1, high):
                    static.append(x)
        if not self.exact:
            static.extend(np.linspace(low, high, quad_segments + 1))
        self.static = np.unique(np.asarray(static, dtype=float))
        sloped = [line for line in lines if line[3] != line[4]]
        self.slope_x0 = np.array([line[1] for line in sloped])
        self.slope_dx = np.array([line[2] - line[1] for line in sloped])
        self.slope_y0 = np.array([line[3] for line in sloped])
        self.slope_dy = np.array([line[4] - line[3] for line in sloped])
        self.n_points = self.static.size + self.slope_x0.size * len(self.mfs)
        if self.exact:
            # Each term is linear on every open interval between static points:
            # mu_k(y) = A[i, k] + B[i, k] y there (sampled inside, so vertical
            # edges at the interval ends do not matter).
            g0, g1 = self.static[:-1], self.static[1:]
            y1, y2 = g0 + 0.25 * (g1 - g0), g0 + 0.75 * (g1 - g0)
            v1 = np.stack([mf(y1) for mf in self.mfs], axis=1)
            v2 = np.stack([mf(y2) for mf in self.mfs], axis=1)
            slope = (v2 - v1) / (y2 - y1)[:, None]
            self.table = np.stack([v1 - slope * y1[:, None], slope], axis=-1)  # (S-1, K, 2)
            if len(self.mfs) <= MAX_TERMS_INCLUSION_EXCLUSION:
                self._prepare_inclusion_exclusion(g0, g1, v1 - slope * y1[:, None], slope)

    def _prepare_inclusion_exclusion(
        self, g0: NDArray[np.float64], g1: NDArray[np.float64],
        intercept: NDArray[np.float64], slope: NDArray[np.float64],
    ) -> None:
        """Static pieces of min_{k in S} mu_k for every non-empty subset S of terms.

        Uses the maximum-minimums identity
        ``max_k a_k = sum_{S != {}} (-1)^(|S|+1) min_{k in S} a_k`` with
        ``a_k = min(alpha_k, mu_k(y))``, so that
        ``min_{k in S} a_k = min(min_{k in S} alpha_k, min_{k in S} mu_k(y))``:
        each subset is ONE static piecewise-linear set cut at one level.
        Every mu_k is linear between static points and any two cross only at
        static points, so each subset minimum is linear there too.
        """
        n_terms = len(self.mfs)
        start = intercept + slope * g0[:, None]  # right limit at g0, (S-1, K)
        end = intercept + slope * g1[:, None]  # left limit at g1
        rows: list[tuple[int, float, float, float, float]] = []  # subset, y0, y1, v0, v1
        signs = []
        members = []
        for mask in range(1, 2**n_terms):
            subset = [k for k in range(n_terms) if mask >> k & 1]
            v0 = start[:, subset].min(axis=1)
            v1 = end[:, subset].min(axis=1)
            keep = (v0 > 1e-15) | (v1 > 1e-15)
            if not keep.any():
                continue
            index = len(signs)
            signs.append(1.0 if len(subset) % 2 else -1.0)
            members.append(mask)
            rows.extend((index, a, b, c, d) for a, b, c, d in
                        zip(g0[keep], g1[keep], v0[keep], v1[keep], strict=True))
        table = np.array(rows, dtype=float).reshape(-1, 5)
        self.ie_subset = table[:, 0].astype(np.intp)
        self.ie_y0 = table[:, 1][:, None]
        self.ie_w = (table[:, 2] - table[:, 1])[:, None]
        self.ie_v0 = table[:, 3][:, None]
        self.ie_v1 = table[:, 4][:, None]
        self.ie_y1 = table[:, 2][:, None]
        dv = self.ie_v1 - self.ie_v0
        self.ie_dv_over_w = dv / self.ie_w
        self.ie_w_over_dv = np.divide(self.ie_w, dv, out=np.zeros_like(dv), where=dv != 0.0)
        self.ie_sign = np.array(signs)[self.ie_subset]
        self.ie_masks = tuple(members)  # bit mask of each kept subset's terms

    def __call__(self, alpha: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Centroid and area of the aggregated set for cut levels ``alpha`` (K, n)."""
        n = alpha.shape[1]
        crisp = np.empty(n)
        area = np.empty(n)
        per_candidate = self.n_points * len(self.mfs) * (3 if self.exact else 4)
        block = max(1, 4_000_000 // per_candidate)
        for start in range(0, n, block):
            stop = min(n, start + block)
            if hasattr(self, "ie_subset"):
                crisp[start:stop], area[start:stop] = self._inclusion_exclusion(alpha[:, start:stop])
                continue
            points = self._breakpoints(alpha[:, start:stop])
            part = self._exact if self.exact else self._quadrature
            crisp[start:stop], area[start:stop] = part(points, alpha[:, start:stop])
        return crisp, area

    def _inclusion_exclusion(
        self, alpha: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Exact area and centroid by the maximum-minimums identity (K small)."""
        # Cut level of every subset: the smallest alpha of its members.
        # Subsets are numbered by bit mask: level(S) = min(level(S - top), alpha_top).
        by_mask = [None] * (1 << alpha.shape[0])
        for mask in range(1, len(by_mask)):
            top = mask.bit_length() - 1
            rest = mask ^ (1 << top)
            by_mask[mask] = alpha[top] if rest == 0 else np.minimum(by_mask[rest], alpha[top])
        level = np.stack([by_mask[mask] for mask in self.ie_masks])
        c = level[self.ie_subset]  # (M, n), one row per static piece
        w, v0, v1, y0 = self.ie_w, self.ie_v0, self.ie_v1, self.ie_y0
        # min(c, v(t)) on a piece v(t) = v0 + (v1 - v0) t / w, t in [0, w], is
        # linear on [0, t*] and [t*, w], t* where v crosses c (clipped to the
        # piece; 0 on a flat piece).
        t_star = (c - v0) * self.ie_w_over_dv
        np.clip(t_star, 0.0, w, out=t_star)
        u_star = v0 + self.ie_dv_over_w * t_star
        np.minimum(u_star, c, out=u_star)
        u0 = np.minimum(v0, c)
        u1 = np.minimum(v1, c)
        y_star = y0 + t_star
        rest = w - t_star
        # Linear piece [a, b] from p to q: area (b - a)(p + q)/2,
        # moment (b - a)(p (2a + b) + q (a + 2b))/6.
        area = t_star * (u0 + u_star) + rest * (u_star + u1)
        moment = t_star * (u0 * (y0 + y_star + y0) + u_star * (y0 + y_star + y_star))
        moment += rest * (u_star * (y_star + y_star + self.ie_y1) + u1 * (y_star + self.ie_y1 + self.ie_y1))
        total_area = 0.5 * (self.ie_sign @ area)
        total_moment = (self.ie_sign @ moment) / 6.0
        with np.errstate(invalid="ignore", divide="ignore"):
            return total_moment / total_area, total_area

    def _breakpoints(self, alpha: NDArray[np.float64]) -> NDArray[np.float64]:
        """Sorted breakpoints (n, P) of the aggregated set."""
        n = alpha.shape[1]
        # Where a sloped segment of some term reaches a cut level alpha_l:
        # y = x0 + (alpha_l - y0) / (y1 - y0) (x1 - x0), kept if on the segment.
        t = (alpha[None, :, :] - self.slope_y0[:, None, None]) / self.slope_dy[:, None, None]
        cross = self.slope_x0[:, None, None] + t * self.slope_dx[:, None, None]
        cross[(t < 0.0) | (t > 1.0)] = self.low
        np.clip(cross, self.low, self.high, out=cross)
        static = np.broadcast_to(self.static, (n, self.static.size))
        points = np.concatenate([static, cross.reshape(-1, n).T], axis=1)
        points.sort(axis=1)
        return points

    def _exact(
        self, points: NDArray[np.float64], alpha: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Exact area and centroid: the aggregated set is linear on each piece."""
        left = points[:, :-1]
        dx = points[:, 1:] - left  # (n, P-1)
        mid = left + 0.5 * dx
        # Static interval holding each piece (the pieces refine the intervals).
        interval = np.zeros(mid.shape, dtype=np.intp)
        for knot in self.static[1:-1]:
            interval += mid > knot
        # Envelope value and slope at each piece's midpoint, term by term.
        mu = np.zeros(mid.shape)
        mu_slope = np.zeros(mid.shape)
        for k in range(alpha.shape[0]):
            slope = self.table[:, k, 1][interval]
            value = self.table[:, k, 0][interval]
            value += slope * mid  # mu_k(mid), linear on the piece
            cut = alpha[k][:, None]
            slope *= value < cut  # a cut piece is flat
            np.minimum(value, cut, out=value)
            better = value > mu
            np.copyto(mu, value, where=better)
            np.copyto(mu_slope, slope, where=better)
        # A linear piece c + s (y - m) on [m - h/2, m + h/2]: area h c,
        # moment h c m + s h^3 / 12.
        area = np.einsum("ij,ij->i", dx, mu)
        moment = np.einsum("ij,ij->i", dx, mid * mu + mu_slope * dx * dx / 12.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            return moment / area, area

    def _quadrature(
        self, points: NDArray[np.float64], alpha: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Two-point Gauss-Legendre on every piece (for smooth output terms)."""
        left = points[:, :-1]
        dx = points[:, 1:] - left
        nodes = np.stack([left + _GL_LO * dx, left + _GL_HI * dx])  # (2, n, P-1)
        mu = np.zeros_like(nodes)
        for k, mf in enumerate(self.mfs):
            np.maximum(mu, np.minimum(mf(nodes), alpha[k][None, :, None]), out=mu)
        area = 0.5 * np.einsum("ij,kij->i", dx, mu)
        moment = 0.5 * np.einsum("ij,kij->i", dx, mu * nodes)
        with np.errstate(invalid="ignore", divide="ignore"):
            return moment / area, area
