"""GTSAM factors of sonar-fusion: the ground floor, importing nothing from :mod:`fusion`.

Each module holds one family of factors. A custom factor is a typed factory around a closure:
the error function reads its variables from ``this.keys()``, returns the unwhitened error
(predicted minus measured, units in the docstring) and fills Jacobians only when asked; the
caller supplies the noise model. Each family has the form the estimators use, and only that
one:

- :mod:`factors.angles` -- ``wrap_angle`` into [-pi, pi) and ``nearest_branch``.
- :mod:`factors.bearing` -- bearings of a track state: built-in linear factors re-centred on
  the estimate.
- :mod:`factors.motion` -- constant-velocity motion: built-in linear factors
  (``JacobianFactor`` in a ``LinearContainerFactor``), set up for a whole chain.
- :mod:`factors.target` -- true bearing of a constant-velocity target: one vector
  ``CustomFactor`` per batch of bearings, analytic Jacobians.
- :mod:`factors.tdoa` (with :mod:`factors.tdoa.model` and :mod:`factors.tdoa.factors`) -- time
  differences of arrival: the model, the factories and the one-source solve.
- :mod:`factors.weighted` -- association weights read live from an array, one per factor or
  one per row of a vector factor.
- :mod:`factors.testing` -- analytic Jacobians against central differences.

A Python ``CustomFactor`` costs a callback per evaluation; the built-in forms are evaluated and
linearised in C++, and a vector factor replaces many callbacks by one.
"""
