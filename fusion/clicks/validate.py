"""TDOA validation: features of the second-order smoothed click map (SCM2) and a GMM likelihood ratio.

Implements step 50 of *Localization of Short Duration Periodic Signals* (Baggenstoss, NUWC
102089), paragraphs [0036]-[0038], eq. (7)-(11). A correlation peak between two hydrophones'
click maps is a valid TDOA when the SCM2 at that lag — the estimate of the source click train —
looks like a click train: its autocorrelation function (ACF) ripples at the inter-click interval
(ICI) and its power spectrum peaks at 1/ICI. Four features summarise that shape
(:func:`scm2_features`) and a likelihood ratio of two Gaussian mixtures, trained on valid (H1) and
invalid (H0) examples, scores it (:class:`TdoaValidator`).

Decisions where the method text is silent (all keyword options):

* **ACF.** Linear (not circular) autocorrelation by a zero-padded FFT, smoothed by a Gaussian of
  standard deviation `smooth_s` (default 20 ms, applied as a Gaussian taper of the power
  spectrum) and then normalised to ``r(0) = 1``. The smoothing is what the text calls the
  "smoothed ACF": it merges the jittered ACF peaks of one lag into a ripple and keeps the
  harmonics of 1/ICI below the fundamental in the *specmax* search.
* **specmax** is searched on ``freqs_hz`` (default 0.5-20 Hz in 0.05 Hz steps: ICIs of 0.05-2 s,
  and the DC lobe of the ACF's envelope left out).
* **An all-zero SCM2** (no matched clicks) has no ACF: its feature row is NaN, and
  :meth:`TdoaValidator.llr` scores any non-finite feature row ``-inf`` (never valid).
* **Mixture size.** ``n_components=None`` picks each class's number of components by BIC over
  1..4 (full covariances); an integer fixes it.
* **Features are standardised** (training mean and standard deviation) before the mixtures; the
  likelihood ratio does not depend on that affine map (its Jacobian cancels between H1 and H0),
  it only keeps the mixtures' fit well conditioned.
* **Threshold.** By default the LLR level at which a `target_far` (1 %) fraction of the training
  invalid examples is accepted (a target false-accept rate), or the equal-error level with
  ``threshold_rule="eer"``.

Examples
--------
>>> import numpy as np
>>> fs, n = 3000.0, 36000
>>> t = np.arange(n) / fs
>>> train = sum(np.exp(-0.5 * ((t - t0) / 1e-3) ** 2) for t0 in np.arange(0.2, 12.0, 0.37))
>>> z = scm2_features(train, fs)
>>> round(float(z[0]), 1)                     # specmax near 1 / 0.37 s
2.7
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from threadpoolctl import threadpool_limits

from fusion.clicks.mixture import GaussianMixtureArrays, fit_mixture
from fusion.clicks.validate_features import FEATURE_NAMES, default_freqs_hz, scm2_features

__all__ = [
    "DEFAULT_MODEL_PATH",
    "V1_MODEL_PATH",
    "FEATURE_NAMES",
    "MODEL_FORMAT",
    "MODEL_VERSION",
    "GaussianMixtureArrays",
    "TdoaValidator",
    "default_freqs_hz",
    "scm2_features",
    "train_validator",
]

logger = logging.getLogger(__name__)

#: ``format`` key of a saved validator model.
MODEL_FORMAT = "fusion.clicks.TdoaValidator"
#: ``version`` key of a saved validator model this module reads and writes.
MODEL_VERSION = 1
#: The shipped model: ``fusion train-validator --simulated 40`` (varied scenarios, mean ICIs
#: over 0.2-1.0 s; docs/localization.md section 11).
DEFAULT_MODEL_PATH = Path(__file__).parent / "data" / "validator_v2.npz"
#: The model shipped before it (mean ICIs 0.25-0.6 s only), kept for the ablation
#: ``fusion localize --validator .../validator_v1.npz --llr-threshold 0``.
V1_MODEL_PATH = Path(__file__).parent / "data" / "validator_v1.npz"


# --------------------------------------------------------------------------------------------
# the validator (eq. 11)
# --------------------------------------------------------------------------------------------
_MODEL_KEYS = (
    "format", "version", "feature_names", "feature_mean", "feature_scale", "threshold",
    "h1_weights", "h1_means", "h1_covariances", "h0_weights", "h0_means", "h0_covariances",
)


@dataclass(frozen=True)
class TdoaValidator:
    """Likelihood-ratio test of a TDOA's SCM2 features: valid (H1) against invalid (H0).

    Attributes
    ----------
    valid : GaussianMixtureArrays
        Mixture of the standardised features under H1 (valid TDOA).
    invalid : GaussianMixtureArrays
        Mixture of the standardised features under H0 (invalid TDOA).
    feature_mean : ndarray, shape (4,)
        Mean subtracted from ``z`` before the mixtures (feature units, see :data:`FEATURE_NAMES`).
    feature_scale : ndarray, shape (4,)
        Positive scale ``z`` is divided by after the mean is subtracted.
    threshold : float
        LLR level above which a TDOA is valid.

    Notes
    -----
    *Localization of Short Duration Periodic Signals*, eq. (11): ``L = log p(z|H1) - log p(z|H0)``
    with each density a Gaussian mixture; peaks with ``L`` at or below the threshold are dropped.
    Both mixtures see the same standardised ``(z - feature_mean) / feature_scale``; the
    Jacobian of that map cancels in ``L``, so ``L`` is the likelihood ratio of ``z`` itself.

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> v = TdoaValidator.fit(rng.normal(1, 1, (200, 4)), rng.normal(-1, 1, (200, 4)), n_components=1)
    >>> v.is_valid(np.array([[2.0, 2, 2, 2], [-2, -2, -2, -2]])).tolist()
    [True, False]
    """

    valid: GaussianMixtureArrays
    invalid: GaussianMixtureArrays
    feature_mean: NDArray[np.float64]
    feature_scale: NDArray[np.float64]
    threshold: float = 0.0

    def __post_init__(self) -> None:
        d = self.valid.means.shape[1]
        if self.invalid.means.shape[1] != d:
            raise ValueError("the H1 and H0 mixtures must have the same dimension")
        for name in ("feature_mean", "feature_scale"):
            a = np.array(getattr(self, name), dtype=float).ravel()
            if a.shape != (d,) or not np.all(np.isfinite(a)):
                raise ValueError(f"{name} must hold {d} finite values, got {a}")
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if not np.all(self.feature_scale > 0):
            raise ValueError("feature_scale must be positive")
        object.__setattr__(self, "threshold", float(self.threshold))
        if not np.isfinite(self.threshold):
            raise ValueError(f"threshold must be finite, got {self.threshold}")

    def llr(self, z: ArrayLike) -> NDArray[np.float64]:
        """Log likelihood ratio ``log p(z|H1) - log p(z|H0)`` of feature rows (eq. 11).

        Parameters
        ----------
        z : array_like, shape (m, 4) or (4,)
            Feature vectors from :func:`scm2_features`.

        Returns
        -------
        ndarray, shape (m,)
            LLR per row (``m = 1`` for a single vector); ``-inf`` for a row with a non-finite
            feature (an empty SCM2).
        """
        x = np.atleast_2d(np.asarray(z, dtype=float))
        d = self.feature_mean.shape[0]
        if x.ndim != 2 or x.shape[1] != d:
            raise ValueError(f"z must have shape (m, {d}), got {np.shape(z)}")
        ok = np.all(np.isfinite(x), axis=1)
        out = np.full(x.shape[0], -np.inf)
        if np.any(ok):
            xs = (x[ok] - self.feature_mean) / self.feature_scale
            out[ok] = self.valid.log_pdf(xs) - self.invalid.log_pdf(xs)
        return out

    def is_valid(self, z: ArrayLike, *, threshold: float | None = None) -> NDArray[np.bool_]:
        """Whether each feature row passes, ``llr(z) > threshold``.

        Parameters
        ----------
        z : array_like, shape (m, 4) or (4,)
            Feature vectors.
        threshold : float, optional
            LLR level; default the validator's :attr:`threshold`.

        Returns
        -------
        ndarray of bool, shape (m,)
        """
        level = self.threshold if threshold is None else float(threshold)
        return self.llr(z) > level

    # ---------------------------------------------------------------------------- training
    @classmethod
    def fit(
        cls,
        z_valid: ArrayLike,
        z_invalid: ArrayLike,
        *,
        n_components: int | None = None,
        seed: int = 0,
        threshold_rule: Literal["far", "eer"] = "far",
        target_far: float = 0.01,
    ) -> TdoaValidator:
        """Train the two mixtures and pick the threshold on labelled feature vectors.

        Parameters
        ----------
        z_valid : array_like, shape (n1, 4)
            Features of valid TDOAs (H1).
        z_invalid : array_like, shape (n0, 4)
            Features of invalid TDOAs (H0).
        n_components : int, optional
            Components per mixture; default: chosen per class by BIC over 1..4.
        seed : int, optional
            Seed of the mixtures' initialisation.
        threshold_rule : {"far", "eer"}, optional
            ``"far"``: the smallest level that accepts at most `target_far` of the training
            invalid examples; ``"eer"``: the level where the training false-accept and
            false-reject rates are equal.
        target_far : float, optional
            Target false-accept rate of the ``"far"`` rule, in (0, 1).

        Returns
        -------
        TdoaValidator

        Raises
        ------
        ValueError
            If a feature array is not ``(n, 4)``, holds non-finite rows or is too short.

        Notes
        -----
        Mixtures: :class:`sklearn.mixture.GaussianMixture` with full covariances, ``n_init=3``,
        ``random_state=seed``, on features standardised by the pooled training mean and
        standard deviation.
        """
        d = len(FEATURE_NAMES)
        z1 = _training_rows("z_valid", z_valid, d)
        z0 = _training_rows("z_invalid", z_invalid, d)
        if n_components is not None and not (isinstance(n_components, int | np.integer)
                                             and 1 <= n_components <= 16):
            raise ValueError(f"n_components must be an integer in 1..16 or None, got {n_components!r}")
        if threshold_rule not in ("far", "eer"):
            raise ValueError(f"threshold_rule must be 'far' or 'eer', got {threshold_rule!r}")
        if not 0.0 < float(target_far) < 1.0:
            raise ValueError(f"target_far must be in (0, 1), got {target_far!r}")
        pooled = np.vstack([z1, z0])
        mean = pooled.mean(axis=0)
        scale = pooled.std(axis=0)
        scale = np.where(scale > 0, scale, 1.0)
        with threadpool_limits(1):  # tiny problems: threaded BLAS only loses on a busy machine
            gm1 = fit_mixture((z1 - mean) / scale, n_components, seed)
            gm0 = fit_mixture((z0 - mean) / scale, n_components, seed)
        model = cls(GaussianMixtureArrays.from_sklearn(gm1), GaussianMixtureArrays.from_sklearn(gm0),
                    mean, scale, 0.0)
        l1, l0 = model.llr(z1), model.llr(z0)
        if threshold_rule == "far":
            level = float(np.quantile(l0, 1.0 - float(target_far), method="higher"))
        else:
            level = _equal_error_level(l1, l0)
        logger.info(
            "TDOA validator: %d+%d components, threshold %.3f accepts %.1f %% valid, %.1f %% "
            "invalid training examples", gm1.n_components, gm0.n_components, level,
            100 * np.mean(l1 > level), 100 * np.mean(l0 > level),
        )
        return cls(model.valid, model.invalid, mean, scale, level)

    # ---------------------------------------------------------------------------- files
    def save(self, path: str | Path) -> None:
        """Write the model to an ``.npz`` file (plain arrays, no pickled objects).

        Keys: ``format``, ``version`` (:data:`MODEL_FORMAT`, :data:`MODEL_VERSION`),
        ``feature_names``, ``feature_mean``, ``feature_scale``, ``threshold`` and
        ``h{1,0}_{weights,means,covariances}``.
        """
        arrays = {
            "format": np.array(MODEL_FORMAT),
            "version": np.array(MODEL_VERSION),
            "feature_names": np.array(FEATURE_NAMES),
            "feature_mean": self.feature_mean,
            "feature_scale": self.feature_scale,
            "threshold": np.array(self.threshold),
        }
        for tag, gm in (("h1", self.valid), ("h0", self.invalid)):
            arrays[f"{tag}_weights"] = gm.weights
            arrays[f"{tag}_means"] = gm.means
            arrays[f"{tag}_covariances"] = gm.covariances
        with open(path, "wb") as fh:
            np.savez(fh, **arrays)

    @classmethod
    def load(cls, path: str | Path) -> TdoaValidator:
        """Read a model written by :meth:`save`.

        Raises
        ------
        FileNotFoundError
            If `path` does not exist.
        ValueError
            Naming the file, if it is not an ``.npz`` archive of plain arrays, is of another
            format or version, lacks keys or holds invalid arrays.
        """
        path = Path(path)
        try:
            archive = np.load(path, allow_pickle=False)
        except FileNotFoundError:
            raise
        except (ValueError, OSError, EOFError) as err:
            raise ValueError(f"{path}: not a TDOA validator model (npz archive): {err}") from None
        if not isinstance(archive, np.lib.npyio.NpzFile):
            raise ValueError(f"{path}: not a TDOA validator model (npz archive)")
        with archive:
            fmt = str(archive["format"][()]) if "format" in archive.files else None
            if fmt != MODEL_FORMAT:
                raise ValueError(f"{path}: format {fmt!r} is not a TDOA validator model "
                                 f"({MODEL_FORMAT!r})")
            missing = [k for k in _MODEL_KEYS if k not in archive.files]
            if missing:
                raise ValueError(f"{path}: TDOA validator model lacks keys {missing}")
            version = archive["version"]
            if not (np.issubdtype(version.dtype, np.integer) and version.shape == ()
                    and int(version) == MODEL_VERSION):
                raise ValueError(f"{path}: TDOA validator model version {version.tolist()!r}; this "
                                 f"code reads version {MODEL_VERSION}")
            names = tuple(str(s) for s in archive["feature_names"])
            if names != FEATURE_NAMES:
                raise ValueError(f"{path}: features {names} differ from {FEATURE_NAMES}")
            a = {k: np.array(archive[k]) for k in _MODEL_KEYS[3:]}
        try:
            return cls(
                GaussianMixtureArrays(a["h1_weights"], a["h1_means"], a["h1_covariances"]),
                GaussianMixtureArrays(a["h0_weights"], a["h0_means"], a["h0_covariances"]),
                a["feature_mean"], a["feature_scale"], float(a["threshold"]),
            )
        except (ValueError, TypeError) as err:
            raise ValueError(f"{path}: invalid TDOA validator model: {err}") from None


def train_validator(
    z_valid: ArrayLike,
    z_invalid: ArrayLike,
    *,
    n_components: int | None = None,
    seed: int = 0,
    threshold_rule: Literal["far", "eer"] = "far",
    target_far: float = 0.01,
) -> TdoaValidator:
    """Train a :class:`TdoaValidator` on labelled feature vectors (see :meth:`TdoaValidator.fit`).

    Parameters
    ----------
    z_valid : array_like, shape (n1, 4)
        Features of valid TDOAs.
    z_invalid : array_like, shape (n0, 4)
        Features of invalid TDOAs.
    n_components, seed, threshold_rule, target_far
        As in :meth:`TdoaValidator.fit`.

    Returns
    -------
    TdoaValidator
    """
    return TdoaValidator.fit(z_valid, z_invalid, n_components=n_components, seed=seed,
                             threshold_rule=threshold_rule, target_far=target_far)


def _training_rows(name: str, z: ArrayLike, d: int) -> NDArray[np.float64]:
    x = np.asarray(z, dtype=float)
    if x.ndim != 2 or x.shape[1] != d:
        raise ValueError(f"{name} must have shape (n, {d}), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} holds non-finite features (empty SCM2s cannot train a mixture)")
    if x.shape[0] < 10:
        raise ValueError(f"{name} needs at least 10 rows, got {x.shape[0]}")
    return x


def _equal_error_level(l1: NDArray[np.float64], l0: NDArray[np.float64]) -> float:
    """LLR level where the false-accept rate of `l0` equals the false-reject rate of `l1`."""
    levels = np.unique(np.concatenate([l1, l0]))
    far = 1.0 - np.searchsorted(np.sort(l0), levels, side="right") / l0.size  # P(l0 > level)
    frr = np.searchsorted(np.sort(l1), levels, side="right") / l1.size  # P(l1 <= level)
    return float(levels[np.argmin(np.abs(far - frr))])
