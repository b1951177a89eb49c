"""One window's localized sources, and the weighted TDOA solve they come from.

:class:`SourceFix` (position, ``gtsam.Marginals`` covariance, the TDOAs it uses, observability
flags) and :class:`LocalizationOutput` (all sources of a window) are what
:class:`fusion.localization.localize.MultiSourceLocalizer` returns; :func:`solve_weighted` is the
weighted least-squares position on a one-factor graph
(:func:`factors.tdoa.weighted_tdoa_vector_factor`) used to polish and to test fixes.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (22): the position of a source from its
TDOAs weighted by their association with it.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np
from numpy.typing import NDArray

from factors.tdoa import weighted_tdoa_vector_factor
from fusion.localization.window_tdoas import WindowTdoas
from fusion.types import frozen_array

__all__ = ["LocalizationOutput", "SourceFix", "solve_weighted", "weighted_cost", "weighted_graph"]



@dataclass(frozen=True)
class SourceFix:
    """One localized source of a window.

    Attributes
    ----------
    position : ndarray, shape (3,)
        Position, m (z up).
    covariance : ndarray, shape (3, 3)
        Marginal covariance from ``gtsam.Marginals`` at `position` with the fix's TDOA weights,
        m^2; NaN where the information is singular.
    information : ndarray, shape (3, 3)
        Position information ``J^T W J`` of the weighted TDOAs, m^-2 (finite even when singular).
    weights : ndarray, shape (M,)
        Weight of each of the window's TDOAs in this fix, in [0, 1].
    tdoas_used : int
        TDOAs of weight > 0.5.
    residual_rms_s : float
        RMS delay residual of those TDOAs, s.
    condition_number : float
        Largest over smallest eigenvalue of `information` (inf when singular).
    observable : bool
        False when the geometry leaves a direction (nearly) unfixed: condition number above the
        localizer's ``max_condition``, or a mirror solution fits as well.
    mirror_ambiguous : bool
        Whether the mirror test found a distinct, equally good solution.
    mirror_position : ndarray, shape (3,)
        That solution, m; NaN when there is none.
    paths : ndarray of int, shape (M,), optional
        Path pair along which the fix reads each TDOA (index into
        :data:`fusion.localization.surface_paths.PATHS`: 0 direct, 1 both surface-reflected, 2 direct
        then reflected, 3 reflected then direct), -1 for a TDOA it does not hold. Default (None):
        every TDOA read along direct paths.
    """

    position: NDArray[np.float64]
    covariance: NDArray[np.float64]
    information: NDArray[np.float64]
    weights: NDArray[np.float64]
    tdoas_used: int
    residual_rms_s: float
    condition_number: float
    observable: bool
    mirror_ambiguous: bool
    mirror_position: NDArray[np.float64]
    paths: NDArray[np.intp] | None = None

    def __post_init__(self) -> None:
        for name in ("position", "covariance", "information", "weights", "mirror_position"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        w = self.weights
        paths = np.where(w > 0.5, 0, -1) if self.paths is None else np.asarray(self.paths)
        if paths.shape != w.shape:
            raise ValueError(f"paths must have one entry per TDOA ({w.shape}), got {paths.shape}")
        paths = paths.astype(np.intp)
        paths.setflags(write=False)
        object.__setattr__(self, "paths", paths)


@dataclass(frozen=True)
class LocalizationOutput:
    """All sources of one window.

    Attributes
    ----------
    sources : tuple of SourceFix
        The sources, the one using most TDOAs first.
    method : str
        The method used (one of :data:`METHODS`).
    clutter_weights : ndarray, shape (M,)
        Weight of each TDOA left to no source, ``1 - sum_k w_km`` clipped to [0, 1].
    candidates : ndarray, shape (K, 3)
        Starting candidates, m.
    iterations : int
        Competition iterations (0 for the other methods).
    converged : bool
        Whether the competition converged (True for the other methods).
    """

    sources: tuple[SourceFix, ...]
    method: str
    clutter_weights: NDArray[np.float64]
    candidates: NDArray[np.float64]
    iterations: int
    converged: bool


def weighted_graph(tdoas: WindowTdoas, pos: NDArray, w: NDArray) -> tuple:
    """One-factor graph of the weighted TDOAs at `pos`: (graph, values, key)."""
    key = gtsam.symbol("x", 0)
    weights = np.array(w, dtype=float)
    graph = gtsam.NonlinearFactorGraph()
    graph.add(weighted_tdoa_vector_factor(gtsam.noiseModel.Diagonal.Sigmas(np.asarray(tdoas.sigmas)),
                                          key, tdoas.sensors, tdoas.pairs, tdoas.taus, weights,
                                          c=tdoas.c))
    values = gtsam.Values()
    values.insert(key, gtsam.Point3(*np.asarray(pos, dtype=float)))
    return graph, values, key


def weighted_cost(tdoas: WindowTdoas, pos: NDArray, w: NDArray) -> float:
    """Graph error: half the weighted sum of squared whitened residuals."""
    r = (tdoas.predicted(pos) - tdoas.taus) / np.asarray(tdoas.sigmas)
    return float(0.5 * np.sum(np.maximum(w, 0.0) * r * r))


def solve_weighted(tdoas: WindowTdoas, start: NDArray, w: NDArray, iterations: int = 50,
           tol: float = 1e-12) -> NDArray:
    """Weighted least-squares position from `start` (Levenberg-Marquardt on a one-factor graph).

    `tol` is the relative decrease of the error at which it stops.
    """
    graph, values, key = weighted_graph(tdoas, start, w)
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(iterations)
    params.setRelativeErrorTol(tol)
    params.setAbsoluteErrorTol(1e-20)
    result = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    return np.asarray(result.atPoint3(key), dtype=float)
