"""Rule antecedents and rules: fuzzy propositions built from Python objects, never strings.

Section 4 of "Target tracking using fuzzy logic association" ("System rules"): an antecedent
is an expression over ``variable is term`` atoms combined with AND (min), OR (max) and NOT
(``1 - mu``), written ``a & b``, ``a | b``, ``~a`` or :class:`And`, :class:`Or`, :class:`Not`;
a :class:`Rule` adds its weighted firing strength to one output term (Section 6, additive
implication). Both round-trip through ``to_dict`` / ``from_dict`` as JSON-ready data.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from fusion.active.fuzzy.membership import _finite

__all__ = ["And", "Expression", "Is", "Not", "Or", "Rule", "expression_from_dict"]


class Expression(ABC):
    """A fuzzy proposition over input variables; combine with ``&``, ``|``, ``~``."""

    def __and__(self, other: Expression) -> And:
        return And(self, other)

    def __or__(self, other: Expression) -> Or:
        return Or(self, other)

    def __invert__(self) -> Not:
        return Not(self)

    @abstractmethod
    def degree(self, memberships: Mapping[tuple[str, str], NDArray[np.float64]]) -> NDArray[np.float64]:
        """Degree of truth (n,) given the membership degree of every atom."""

    @abstractmethod
    def atoms(self) -> Iterator[Is]:
        """Every ``Is`` atom of the expression (with repeats)."""

    @abstractmethod
    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form: ``{"is": [var, term]}``, ``{"not": e}``, ``{"and": [..]}``, ``{"or": [..]}``."""

    def variables(self) -> frozenset[str]:
        """Names of the input variables the expression reads."""
        return frozenset(atom.variable for atom in self.atoms())


@dataclass(frozen=True)
class Is(Expression):
    """Atom ``variable is term``: the term's membership degree of the input.

    Parameters
    ----------
    variable : str
        Input variable name.
    term : str
        One of that variable's term names.
    """

    variable: str
    term: str

    def __post_init__(self) -> None:
        for key in ("variable", "term"):
            value = getattr(self, key)
            if not isinstance(value, str) or not value:
                raise ValueError(f"Is: {key} must be a non-empty string, got {value!r}")

    def degree(self, memberships: Mapping[tuple[str, str], NDArray[np.float64]]) -> NDArray[np.float64]:
        return memberships[(self.variable, self.term)]

    def atoms(self) -> Iterator[Is]:
        yield self

    def to_dict(self) -> dict[str, Any]:
        return {"is": [self.variable, self.term]}


@dataclass(frozen=True)
class Not(Expression):
    """Complement ``1 - mu`` of an expression."""

    operand: Expression

    def __post_init__(self) -> None:
        if not isinstance(self.operand, Expression):
            raise ValueError(f"Not: operand must be an Expression, got {self.operand!r}")

    def degree(self, memberships: Mapping[tuple[str, str], NDArray[np.float64]]) -> NDArray[np.float64]:
        return 1.0 - self.operand.degree(memberships)

    def atoms(self) -> Iterator[Is]:
        return self.operand.atoms()

    def to_dict(self) -> dict[str, Any]:
        return {"not": self.operand.to_dict()}


@dataclass(frozen=True, init=False)
class _Combination(Expression):
    operands: tuple[Expression, ...]
    _key: ClassVar[str]

    def __init__(self, *operands: Expression) -> None:
        flat: list[Expression] = []
        for operand in operands:
            if not isinstance(operand, Expression):
                raise ValueError(
                    f"{type(self).__name__}: operands must be Expressions, got {operand!r}"
                )
            # (a & b) & c is And(a, b, c): min and max are associative.
            flat.extend(operand.operands if type(operand) is type(self) else (operand,))
        if len(flat) < 2:
            raise ValueError(f"{type(self).__name__}: needs at least two operands")
        object.__setattr__(self, "operands", tuple(flat))

    def atoms(self) -> Iterator[Is]:
        for operand in self.operands:
            yield from operand.atoms()

    def to_dict(self) -> dict[str, Any]:
        return {self._key: [operand.to_dict() for operand in self.operands]}


class And(_Combination):
    """Conjunction: the minimum of the operands' degrees (``a & b``)."""

    _key = "and"

    def degree(self, memberships: Mapping[tuple[str, str], NDArray[np.float64]]) -> NDArray[np.float64]:
        out = self.operands[0].degree(memberships)
        for operand in self.operands[1:]:
            out = np.minimum(out, operand.degree(memberships))
        return out


class Or(_Combination):
    """Disjunction: the maximum of the operands' degrees (``a | b``)."""

    _key = "or"

    def degree(self, memberships: Mapping[tuple[str, str], NDArray[np.float64]]) -> NDArray[np.float64]:
        out = self.operands[0].degree(memberships)
        for operand in self.operands[1:]:
            out = np.maximum(out, operand.degree(memberships))
        return out


def expression_from_dict(data: Any) -> Expression:
    """Build an antecedent from its :meth:`Expression.to_dict` form.

    Parameters
    ----------
    data : mapping
        Exactly one key: ``"is"`` ([variable, term]), ``"not"`` (expression),
        ``"and"`` or ``"or"`` (list of at least two expressions).

    Returns
    -------
    Expression

    Raises
    ------
    ValueError
        On any other shape.
    """
    if not isinstance(data, Mapping) or len(data) != 1:
        raise ValueError(
            f"expression must be an object with one key is/not/and/or, got {data!r}"
        )
    ((key, value),) = data.items()
    if key == "is":
        if not (isinstance(value, Sequence) and not isinstance(value, str) and len(value) == 2):
            raise ValueError(f"'is' needs [variable, term], got {value!r}")
        return Is(value[0], value[1])
    if key == "not":
        return Not(expression_from_dict(value))
    if key in ("and", "or"):
        if not isinstance(value, Sequence) or isinstance(value, str):
            raise ValueError(f"'{key}' needs a list of expressions, got {value!r}")
        operands = [expression_from_dict(item) for item in value]
        return And(*operands) if key == "and" else Or(*operands)
    raise ValueError(f"unknown expression operator {key!r} (expected is, not, and, or)")


@dataclass(frozen=True)
class Rule:
    """``IF antecedent THEN output is consequent`` with a weight.

    Parameters
    ----------
    antecedent : Expression
        Built from :class:`Is` atoms with ``&``, ``|``, ``~``.
    consequent : str
        A term of the system's output variable.
    weight : float, optional
        Finite, >= 0 (default 1). The rule adds ``weight * strength`` to its
        consequent's activation (additive implication, Section 6).

    Examples
    --------
    >>> Rule(Is("snr_db", "high") & ~Is("aspect_deg", "specular"), "low", weight=0.6).weight
    0.6
    """

    antecedent: Expression
    consequent: str
    weight: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.antecedent, Expression):
            raise ValueError(f"rule antecedent must be an Expression, got {self.antecedent!r}")
        if not isinstance(self.consequent, str) or not self.consequent:
            raise ValueError(f"rule consequent must be a term name, got {self.consequent!r}")
        weight = _finite("rule", weight=self.weight)["weight"]
        if weight < 0.0:
            raise ValueError(f"rule weight must be >= 0, got {weight:g}")
        object.__setattr__(self, "weight", weight)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form ``{"if": expression, "then": term, "weight": w}``."""
        return {"if": self.antecedent.to_dict(), "then": self.consequent, "weight": self.weight}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Rule:
        """Inverse of :meth:`to_dict` (``weight`` optional, default 1)."""
        if not isinstance(data, Mapping):
            raise ValueError(f"rule must be an object, got {data!r}")
        extra = set(data) - {"if", "then", "weight"}
        if extra or "if" not in data or "then" not in data:
            raise ValueError(f"rule needs keys if, then (and optional weight), got {sorted(data)}")
        return cls(expression_from_dict(data["if"]), data["then"], data.get("weight", 1.0))
