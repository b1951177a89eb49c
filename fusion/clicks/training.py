"""Deprecated import path: use :mod:`fusion.simulate.scm2`; this module goes in the next release.

Why: the synthetic SCM2 series are drawn from simulated click trains, and no estimator package
imports a simulator.
"""

from fusion._deprecated import moved_names

__all__ = ["INVALID_KINDS", "KINDS", "SyntheticScm2Set", "scm1_pulse",  # noqa: F822
           "synthetic_scm2", "synthetic_training_set"]

__getattr__ = moved_names(__name__, "fusion.simulate.scm2", __all__, shown="fusion.simulate.scm2")
