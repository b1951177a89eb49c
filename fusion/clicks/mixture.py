"""Gaussian mixtures held as plain arrays, with their own vectorised log density.

The TDOA validator (:mod:`fusion.clicks.validate`) stores its two class-conditional mixtures as
arrays so a model file needs no pickled objects; scikit-learn fits them
(:func:`fit_mixture`) and :meth:`GaussianMixtureArrays.from_sklearn` takes their arrays.

Examples
--------
>>> import numpy as np
>>> gm = GaussianMixtureArrays(np.array([1.0]), np.zeros((1, 2)), np.eye(2)[None])
>>> round(float(gm.log_pdf(np.zeros((1, 2)))[0]), 4)      # -log(2 pi)
-1.8379
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import solve_triangular
from scipy.special import logsumexp

if TYPE_CHECKING:  # imported where a mixture is fitted: scoring needs only the arrays
    from sklearn.mixture import GaussianMixture

__all__ = ["GaussianMixtureArrays", "fit_mixture"]


@dataclass(frozen=True)
class GaussianMixtureArrays:
    """A Gaussian mixture with full covariances, held as plain arrays.

    Attributes
    ----------
    weights : ndarray, shape (k,)
        Component weights (positive, summing to 1).
    means : ndarray, shape (k, d)
        Component means.
    covariances : ndarray, shape (k, d, d)
        Component covariances (symmetric positive definite).
    """

    weights: NDArray[np.float64]
    means: NDArray[np.float64]
    covariances: NDArray[np.float64]

    def __post_init__(self) -> None:
        for name in ("weights", "means", "covariances"):
            a = np.array(getattr(self, name), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        k = self.weights.shape[0] if self.weights.ndim == 1 else -1
        d = self.means.shape[1] if self.means.ndim == 2 else -1
        if k < 1 or self.means.shape != (k, d) or self.covariances.shape != (k, d, d):
            raise ValueError(
                "mixture arrays must have shapes (k,), (k, d), (k, d, d); got "
                f"{self.weights.shape}, {self.means.shape}, {self.covariances.shape}"
            )
        if not (np.all(np.isfinite(self.weights)) and np.all(self.weights > 0)
                and abs(self.weights.sum() - 1.0) < 1e-6):
            raise ValueError("mixture weights must be positive and sum to 1")
        if not (np.all(np.isfinite(self.means)) and np.all(np.isfinite(self.covariances))):
            raise ValueError("mixture means and covariances must be finite")
        try:
            np.linalg.cholesky(self.covariances)
        except np.linalg.LinAlgError:
            raise ValueError("mixture covariances must be positive definite") from None

    @property
    def n_components(self) -> int:
        """Number of components ``k``."""
        return int(self.weights.shape[0])

    @classmethod
    def from_sklearn(cls, gm: GaussianMixture) -> GaussianMixtureArrays:
        """The arrays of a fitted :class:`sklearn.mixture.GaussianMixture` (any covariance type)."""
        k, d = gm.means_.shape
        cov = np.asarray(gm.covariances_, dtype=float)
        if gm.covariance_type == "full":
            full = cov
        elif gm.covariance_type == "tied":
            full = np.broadcast_to(cov, (k, d, d))
        elif gm.covariance_type == "diag":
            full = cov[:, :, None] * np.eye(d)
        else:  # spherical
            full = cov[:, None, None] * np.eye(d)
        return cls(gm.weights_, gm.means_, full)

    def log_pdf(self, x: ArrayLike) -> NDArray[np.float64]:
        """Log density at the rows of `x`.

        Parameters
        ----------
        x : array_like, shape (m, d)
            Points.

        Returns
        -------
        ndarray, shape (m,)
            ``log sum_c w_c N(x; m_c, C_c)``.
        """
        x = np.atleast_2d(np.asarray(x, dtype=float))
        d = self.means.shape[1]
        if x.shape[1] != d:
            raise ValueError(f"points must have {d} columns, got {x.shape[1]}")
        log_comp = np.empty((self.n_components, x.shape[0]))
        for c in range(self.n_components):
            chol = np.linalg.cholesky(self.covariances[c])  # C = L L^T
            y = solve_triangular(chol, (x - self.means[c]).T, lower=True)  # L y = x - m
            log_det = 2.0 * np.sum(np.log(np.diag(chol)))
            log_comp[c] = -0.5 * (d * np.log(2.0 * np.pi) + log_det + np.sum(y**2, axis=0))
        return logsumexp(log_comp + np.log(self.weights)[:, None], axis=0)


def fit_mixture(x: NDArray[np.float64], n_components: int | None, seed: int) -> GaussianMixture:
    """Fit a full-covariance Gaussian mixture, its size chosen by BIC unless given.

    Parameters
    ----------
    x : ndarray, shape (n, d)
        Training points.
    n_components : int or None
        Number of components; None: the size in 1..4 with the lowest BIC.
    seed : int
        ``random_state`` of :class:`sklearn.mixture.GaussianMixture` (``n_init=3``).

    Returns
    -------
    sklearn.mixture.GaussianMixture
    """
    from sklearn.mixture import GaussianMixture

    sizes = range(1, 5) if n_components is None else (int(n_components),)
    best, best_bic = None, np.inf
    for k in sizes:
        if k > x.shape[0]:
            break
        gm = GaussianMixture(k, covariance_type="full", n_init=3, random_state=seed).fit(x)
        bic = gm.bic(x)
        if bic < best_bic:
            best, best_bic = gm, bic
    if best is None:
        raise ValueError(f"{x.shape[0]} training rows are too few for {n_components} components")
    return best
