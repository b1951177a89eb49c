"""Custom GTSAM factors of sonar-fusion.

Each module holds one family of factors, written as typed factories around a closure: the
error function reads its variables from ``this.keys()``, returns the unwhitened 1-D error
(predicted minus measured, units in the docstring) and fills Jacobians only when asked. The
caller supplies the noise model. :mod:`factors.testing` checks Jacobians against central
differences.
"""
