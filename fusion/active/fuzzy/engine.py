"""Fuzzy inference engine: additive implication and centroid output, vectorised over candidates.

Implements the inference of "Target tracking using fuzzy logic association" (Section 4, "System
rules"; Section 6, "Combining rules"): each rule's antecedent is evaluated with AND = min,
OR = max, NOT = 1 - mu; per output term, the firing strengths times the rule weights of all
rules with that consequent are added and clipped to 1 (additive implication); that sum cuts
(min) the term's output set; the crisp output is the centroid of the union (max) of the cut sets
(:class:`fusion.active.fuzzy.centroid.Centroid`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.active.fuzzy.centroid import Centroid
from fusion.active.fuzzy.rules import Rule
from fusion.active.fuzzy.variables import LinguisticVariable

__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "FuzzyResult", "FuzzySystem"]

logger = logging.getLogger(__name__)

FORMAT_NAME = "sonar-fusion fuzzy system"
FORMAT_VERSION = 1


@dataclass(frozen=True)
class FuzzyResult:
    """Outcome of :meth:`FuzzySystem.evaluate` for n candidates.

    Attributes
    ----------
    crisp : ndarray, shape (n,)
        Centroid of the union of cut output sets, in output units; the
        system's ``default`` where no rule fired.
    strengths : ndarray, shape (n_rules, n)
        Firing strength (antecedent degree, before weighting) of each rule;
        0 for skipped rules.
    activations : ndarray, shape (n_terms, n)
        Cut level of each output term: ``min(1, sum of weight * strength)``.
    terms : tuple of str
        Output term names, the rows of ``activations``.
    fired : ndarray of bool, shape (n,)
        Whether any output term has a positive activation.
    skipped : tuple of int
        Indices of rules left out because an input they read was absent.
    missing : tuple of str
        Input variables read by some rule but absent from the inputs.
    """

    crisp: NDArray[np.float64]
    strengths: NDArray[np.float64]
    activations: NDArray[np.float64]
    terms: tuple[str, ...]
    fired: NDArray[np.bool_]
    skipped: tuple[int, ...]
    missing: tuple[str, ...]


class FuzzySystem:
    """Fuzzy inference system with additive implication and centroid output.

    Configure once with the input variables, the output variable and the
    rules; call :meth:`evaluate` with all candidates of a ping at once.

    Parameters
    ----------
    variables : sequence of LinguisticVariable
        Input variables, unique names.
    output : LinguisticVariable
        Output variable; its universe is the defuzzification range.
    rules : sequence of Rule
        At least one; every atom must name a known input variable and term,
        every consequent an output term.
    default : float or None, optional
        Crisp output of candidates for which no rule fires (all activations
        zero): a value in the output universe, or NaN. None (default) means
        the midpoint of the output universe, "no evidence either way".
    quad_segments : int, optional
        Uniform quadrature pieces used only when an output term is smooth
        (Gaussian, sigmoid); default 2048.

    Notes
    -----
    For candidate j (the paper, Sections 4-6):

    * firing strength ``s_r = A_r(x_j)`` with AND = min, OR = max, NOT = 1 - mu;
    * additive implication ``alpha_t = min(1, sum_{r: c_r = t} w_r s_r)``;
    * aggregated set ``mu(y) = max_t min(alpha_t, mu_t(y))``;
    * crisp output ``y* = int y mu(y) dy / int mu(y) dy`` over the universe.

    Examples
    --------
    >>> import numpy as np
    >>> from fusion.active.fuzzy import LinguisticVariable, RightShoulder, Rule, Triangular
    >>> x = LinguisticVariable("x", (0.0, 1.0), {"big": RightShoulder(0.0, 1.0)})
    >>> y = LinguisticVariable("y", (0.0, 1.0), {"lo": Triangular(0.0, 0.0, 1.0),
    ...                                          "hi": Triangular(0.0, 1.0, 1.0)})
    >>> system = FuzzySystem([x], y, [Rule(x["big"], "hi"), Rule(~x["big"], "lo")])
    >>> system.evaluate({"x": np.array([1.0, 0.0])}).crisp.round(4)
    array([0.6667, 0.3333])
    """

    def __init__(
        self,
        variables: Sequence[LinguisticVariable],
        output: LinguisticVariable,
        rules: Sequence[Rule],
        *,
        default: float | None = None,
        quad_segments: int = 2048,
    ) -> None:
        variables = tuple(variables)
        rules = tuple(rules)
        if not variables:
            raise ValueError("fuzzy system needs at least one input variable")
        for variable in (*variables, output):
            if not isinstance(variable, LinguisticVariable):
                raise ValueError(f"not a LinguisticVariable: {variable!r}")
        names = [variable.name for variable in variables]
        duplicates = sorted({name for name in names if names.count(name) > 1})
        if duplicates:
            raise ValueError(f"duplicate input variable names: {', '.join(duplicates)}")
        if output.name in names:
            raise ValueError(f"output variable {output.name!r} is also an input variable")
        if not rules:
            raise ValueError("fuzzy system needs at least one rule")
        by_name = {variable.name: variable for variable in variables}
        for index, rule in enumerate(rules):
            if not isinstance(rule, Rule):
                raise ValueError(f"rule {index}: not a Rule: {rule!r}")
            for atom in rule.antecedent.atoms():
                if atom.variable not in by_name:
                    raise ValueError(f"rule {index}: unknown input variable {atom.variable!r}")
                if atom.term not in by_name[atom.variable].terms:
                    raise ValueError(
                        f"rule {index}: variable {atom.variable!r} has no term {atom.term!r}"
                    )
            if rule.consequent not in output.terms:
                raise ValueError(
                    f"rule {index}: output {output.name!r} has no term {rule.consequent!r}"
                )
        if isinstance(quad_segments, bool) or not isinstance(quad_segments, (int, np.integer)) \
                or quad_segments < 16:
            raise ValueError(f"quad_segments must be an integer >= 16, got {quad_segments!r}")
        low, high = output.universe
        if default is None:
            default = 0.5 * (low + high)
        default = float(default)
        if not (math.isnan(default) or low <= default <= high):
            raise ValueError(
                f"default {default:g} must lie in the output universe [{low:g}, {high:g}] or be NaN"
            )
        self.variables: tuple[LinguisticVariable, ...] = variables
        self.output: LinguisticVariable = output
        self.rules: tuple[Rule, ...] = rules
        self.default: float = default
        self.quad_segments: int = int(quad_segments)
        self._by_name = by_name
        self._terms = tuple(output.terms)
        self._rule_vars = tuple(rule.antecedent.variables() for rule in rules)
        # (n_terms, n_rules): weight of rule r in row of its consequent term.
        self._implication = np.zeros((len(self._terms), len(rules)))
        for index, rule in enumerate(rules):
            self._implication[self._terms.index(rule.consequent), index] = rule.weight
        self._centroid = Centroid(output, quad_segments=self.quad_segments)
        self._reported: set[frozenset[str]] = set()

    @property
    def input_names(self) -> tuple[str, ...]:
        """Names of the input variables, in order."""
        return tuple(variable.name for variable in self.variables)

    def evaluate(self, inputs: Mapping[str, ArrayLike]) -> FuzzyResult:
        """Rank n candidates in one call.

        Parameters
        ----------
        inputs : mapping of str to array_like, shape (n,)
            Any subset of the input variables (names not in the system are
            ignored). Arrays of equal length n >= 0; scalars broadcast.
            Values may be +-inf, not NaN.

        Returns
        -------
        FuzzyResult
            Crisp outputs, per-rule strengths, per-term activations and the
            rules skipped because an input they read is absent (logged once
            per system and set of missing inputs).

        Raises
        ------
        ValueError
            No relevant input, arrays of different lengths or not 1-D, NaN.
        """
        arrays: dict[str, NDArray[np.float64]] = {}
        for name, value in inputs.items():
            if name not in self._by_name:
                continue
            try:
                array = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                raise ValueError(f"input {name!r}: not numeric") from None
            if array.ndim > 1:
                raise ValueError(f"input {name!r}: must be 1-D, got shape {array.shape}")
            if np.isnan(array).any():
                raise ValueError(f"input {name!r}: contains NaN")
            arrays[name] = array
        if not arrays:
            raise ValueError(
                f"no input for any variable of the fuzzy system (expected some of "
                f"{', '.join(self.input_names)}; got {', '.join(map(str, inputs)) or 'nothing'})"
            )
        lengths = {array.size for array in arrays.values() if array.ndim == 1}
        if len(lengths) > 1:
            raise ValueError(
                "inputs have different lengths: "
                + ", ".join(f"{k}={v.size}" for k, v in arrays.items() if v.ndim == 1)
            )
        n = lengths.pop() if lengths else 1
        arrays = {name: np.broadcast_to(array, (n,)) for name, array in arrays.items()}

        skipped = tuple(i for i, names in enumerate(self._rule_vars) if not names <= arrays.keys())
        missing = tuple(sorted(set().union(*(self._rule_vars[i] for i in skipped)) - arrays.keys()))
        if skipped and frozenset(missing) not in self._reported:
            self._reported.add(frozenset(missing))
            logger.warning(
                "fuzzy system: inputs %s absent, rules[%s] left out (numbered from 0, as in "
                "FuzzyResult.skipped)", ", ".join(missing), ", ".join(str(i) for i in skipped),
            )

        memberships: dict[tuple[str, str], NDArray[np.float64]] = {}
        strengths = np.zeros((len(self.rules), n))
        for index, rule in enumerate(self.rules):
            if index in skipped:
                continue
            for atom in rule.antecedent.atoms():
                key = (atom.variable, atom.term)
                if key not in memberships:
                    memberships[key] = self._by_name[atom.variable].terms[atom.term](arrays[atom.variable])
            strengths[index] = rule.antecedent.degree(memberships)

        # Additive implication: alpha_t = min(1, sum over rules r -> t of w_r s_r).
        activations = self._implication @ strengths
        np.minimum(activations, 1.0, out=activations)
        fired = activations.max(axis=0, initial=0.0) > 0.0

        crisp = np.full(n, self.default)
        if fired.any():
            centroid, area = self._centroid(activations[:, fired])
            crisp[fired] = np.where(area > 0.0, centroid, self.default)
        for array in (crisp, strengths, activations, fired):
            array.setflags(write=False)
        return FuzzyResult(crisp, strengths, activations, self._terms, fired, skipped, missing)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (see :func:`load_system` for the format)."""
        return {
            "format": FORMAT_NAME,
            "version": FORMAT_VERSION,
            "variables": [variable.to_dict() for variable in self.variables],
            "output": self.output.to_dict(),
            "rules": [rule.to_dict() for rule in self.rules],
            "default": None if math.isnan(self.default) else self.default,
            "quad_segments": self.quad_segments,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> FuzzySystem:
        """Build a system from :meth:`to_dict` output.

        Raises
        ------
        ValueError
            With the location of the first problem (e.g. ``rules[3]: ...``).
        """
        if not isinstance(data, Mapping):
            raise ValueError("fuzzy system must be a JSON object")
        if data.get("format", FORMAT_NAME) != FORMAT_NAME:
            raise ValueError(f"format must be {FORMAT_NAME!r}, got {data.get('format')!r}")
        if data.get("version", FORMAT_VERSION) != FORMAT_VERSION:
            raise ValueError(f"unsupported version {data.get('version')!r}")
        extra = set(data) - {"format", "version", "variables", "output", "rules", "default",
                             "quad_segments"}
        if extra:
            raise ValueError(f"unknown keys {sorted(extra)}")
        for key in ("variables", "output", "rules"):
            if key not in data:
                raise ValueError(f"missing key {key!r}")
        for key in ("variables", "rules"):
            if not isinstance(data[key], Sequence) or isinstance(data[key], str):
                raise ValueError(f"{key} must be a list")
        variables = []
        for index, item in enumerate(data["variables"]):
            try:
                variables.append(LinguisticVariable.from_dict(item))
            except ValueError as exc:
                raise ValueError(f"variables[{index}]: {exc}") from None
        try:
            output = LinguisticVariable.from_dict(data["output"])
        except ValueError as exc:
            raise ValueError(f"output: {exc}") from None
        rules = []
        for index, item in enumerate(data["rules"]):
            try:
                rules.append(Rule.from_dict(item))
            except ValueError as exc:
                raise ValueError(f"rules[{index}]: {exc}") from None
        default = data.get("default")
        return cls(
            variables, output, rules,
            default=float("nan") if default is None and "default" in data else default,
            quad_segments=data.get("quad_segments", 2048),
        )
