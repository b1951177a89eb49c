"""Bearings-only target motion analysis (TMA) on a factor graph.

A platform (own-ship) with a known track measures true bearings of a target that moves at a
(nearly) constant velocity. The target's position and velocity follow from the bearings only when
the own-ship manoeuvres; the estimator reports its covariance and says when range is unobservable.

Formulation (design notes, "Factor graphs", bearings-only target motion analysis). Two target
models, chosen with ``motion``:

* ``"single"`` (default, the classical TMA): one ``Vector4`` state ``s_0 = [x, y, vx, vy]`` at the
  first bearing time; the bearing taken at ``t_k`` sees ``s_0`` propagated by ``dt = t_k - t_0``.
  All bearings enter through one vector factor
  (:func:`factors.target.target_bearing_batch_factor` with ``dt``): one Python callback per
  evaluation, whatever the number of bearings. Per-time states and covariances follow as
  ``s_k = F(dt) s_0`` and ``P_k = F P_0 F^T``.
* ``"chain"``: one state per bearing time, bearing factors on them (one vector factor per few
  neighbouring states), linked by built-in linear constant-velocity factors
  (:func:`factors.motion.constant_velocity_chain`) with the white-noise-acceleration
  covariance ``Q(dt)`` of a small spectral density ``q``: the target may drift slowly off a
  straight line.

Why ``"single"`` is the default: for a target that holds course it is the exact model, its
covariance is consistent (the chain's process noise makes the covariance conservative for such a
target), it is better conditioned and several times faster. ``"chain"`` suits slowly
manoeuvring targets.

Both models use bearing factors that may be robust (Huber, Cauchy or Tukey, acting on each
bearing alone); a diffuse prior on
the first state (100 km, 100 m/s by default), centred on the initial guess, keeps the optimiser
from wandering along an unobservable range direction and is negligible whenever the bearings
determine the state. Covariances come from ``gtsam.Marginals``; when its Cholesky factorisation
finds the information matrix indeterminate (range unobservable, or a tiny ``q`` against the
diffuse prior), from the singular value decomposition of the dense whitened Jacobian instead
(the same matrix, factored without squaring its condition number).

Initialisation needs no truth and no second solver: closed-form candidates (the pseudo-linear
estimate, and states along the first bearing at geometrically spaced ranges with their
pseudo-linear velocities) are scored by the cost of the graph's bearing factor, with the robust
loss when one is set; the lowest-cost candidate seeds the graph, which one Levenberg-Marquardt
run solves.

Observability: range is unobservable when the own-ship keeps a constant velocity (the target's
relative track can be scaled without changing a single bearing). Three checks flag it, each with a
``logging`` warning and ``TmaResult.observable = False``: the own-ship's largest departure from a
straight constant-speed track fitted to its positions (``min_manoeuvre_m``); that departure seen
from the target, against the bearing noise (``min_manoeuvre_sigmas``); and the relative standard
deviation of the final range along the line of sight (``max_range_rel_sigma``), i.e. an
ill-conditioned information matrix in the range direction. The covariance is first fitted to the
residuals (their variance and lag-one correlation, :mod:`~fusion.passive.tma.confidence`), and
every time gets a range interval (``TmaResult.range_low``, ``range_high``).

Modules: :mod:`~fusion.passive.tma.types` (:class:`OwnshipTrack`, :class:`TmaResult`),
:mod:`~fusion.passive.tma.confidence` (:func:`noise_inflation`, :func:`range_interval`),
:mod:`~fusion.passive.tma.observability` (:func:`ownship_manoeuvre`, :func:`range_rel_sigma`),
:mod:`~fusion.passive.tma.initial` (closed-form starting states),
:mod:`~fusion.passive.tma.estimator` (:class:`BearingsOnlyTMA`).
"""

from fusion.passive.tma.estimator import BearingsOnlyTMA
from fusion.passive.tma.observability import ownship_manoeuvre, range_rel_sigma
from fusion.passive.tma.types import OwnshipTrack, TmaResult

__all__ = [
    "BearingsOnlyTMA", "OwnshipTrack", "TmaResult", "ownship_manoeuvre", "range_rel_sigma",
]
