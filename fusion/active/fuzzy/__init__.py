"""Vectorised fuzzy inference with additive implication and exact centroids.

Implements the inference of "Target tracking using fuzzy logic association" (Section 4,
"System rules"; Section 5, "Membership functions"; Section 6, "Combining rules"). Everything is
data built from Python objects, one role per module:

- :mod:`~fusion.active.fuzzy.membership`: membership functions, small frozen dataclasses that act
  as vectorised numpy functions;
- :mod:`~fusion.active.fuzzy.rules`: antecedent expressions (``&`` AND, ``|`` OR, ``~`` NOT, or
  :class:`And`, :class:`Or`, :class:`Not`) and weighted rules;
- :mod:`~fusion.active.fuzzy.variables`: linguistic variables (a universe and named terms);
- :mod:`~fusion.active.fuzzy.centroid`: the centroid of the union of cut output sets, exact for
  piecewise-linear sets;
- :mod:`~fusion.active.fuzzy.engine`: :class:`FuzzySystem`, additive implication over all
  candidates of a ping in one call;
- :mod:`~fusion.active.fuzzy.files`: JSON files (:func:`save_system`, :func:`load_system`), so
  users write their own rule sets as data.
"""

from fusion.active.fuzzy.centroid import MAX_TERMS_INCLUSION_EXCLUSION
from fusion.active.fuzzy.engine import FORMAT_NAME, FORMAT_VERSION, FuzzyResult, FuzzySystem
from fusion.active.fuzzy.files import load_system, save_system
from fusion.active.fuzzy.membership import (
    Gaussian,
    LeftShoulder,
    MembershipFunction,
    RightShoulder,
    Sigmoid,
    Trapezoidal,
    Triangular,
    membership_from_dict,
)
from fusion.active.fuzzy.rules import And, Expression, Is, Not, Or, Rule, expression_from_dict
from fusion.active.fuzzy.variables import LinguisticVariable

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "MAX_TERMS_INCLUSION_EXCLUSION",
    "And",
    "Expression",
    "FuzzyResult",
    "FuzzySystem",
    "Gaussian",
    "Is",
    "LeftShoulder",
    "LinguisticVariable",
    "MembershipFunction",
    "Not",
    "Or",
    "RightShoulder",
    "Rule",
    "Sigmoid",
    "Trapezoidal",
    "Triangular",
    "expression_from_dict",
    "load_system",
    "membership_from_dict",
    "save_system",
]
