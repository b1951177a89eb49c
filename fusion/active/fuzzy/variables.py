"""Linguistic variables: a named quantity, its universe and its named fuzzy terms."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from fusion.active.fuzzy.membership import MembershipFunction, membership_from_dict
from fusion.active.fuzzy.rules import Is

__all__ = ["LinguisticVariable"]


@dataclass(frozen=True)
class LinguisticVariable:
    """A named quantity with a universe and named fuzzy terms.

    Parameters
    ----------
    name : str
        Variable name, the key of its input array (for example ``"snr_db"``).
    universe : tuple of float
        ``(low, high)``, finite, ``low < high``, in the variable's units. For
        the output variable it is the defuzzification range; for inputs it
        documents the useful range (inputs outside it are allowed).
    terms : mapping of str to MembershipFunction
        Term name -> fuzzy set.

    Examples
    --------
    >>> from fusion.active.fuzzy import RightShoulder
    >>> snr = LinguisticVariable("snr_db", (0.0, 40.0), {"high": RightShoulder(12.0, 20.0)})
    >>> snr["high"]
    Is(variable='snr_db', term='high')
    """

    name: str
    universe: tuple[float, float]
    terms: Mapping[str, MembershipFunction] = field(hash=False)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"variable name must be a non-empty string, got {self.name!r}")
        try:
            low, high = (float(v) for v in self.universe)
        except (TypeError, ValueError):
            raise ValueError(
                f"variable {self.name!r}: universe must be (low, high), got {self.universe!r}"
            ) from None
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise ValueError(
                f"variable {self.name!r}: universe needs finite low < high, got {self.universe!r}"
            )
        if not isinstance(self.terms, Mapping) or not self.terms:
            raise ValueError(f"variable {self.name!r}: needs at least one term")
        for term, mf in self.terms.items():
            if not isinstance(term, str) or not term:
                raise ValueError(f"variable {self.name!r}: term names must be non-empty strings")
            if not isinstance(mf, MembershipFunction):
                raise ValueError(
                    f"variable {self.name!r}, term {term!r}: not a membership function: {mf!r}"
                )
        object.__setattr__(self, "universe", (low, high))
        object.__setattr__(self, "terms", dict(self.terms))

    def __getitem__(self, term: str) -> Is:
        """The atom ``self.name is term`` for building rules."""
        if term not in self.terms:
            raise ValueError(
                f"variable {self.name!r} has no term {term!r} (terms: {', '.join(self.terms)})"
            )
        return Is(self.name, term)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "name": self.name,
            "universe": list(self.universe),
            "terms": {term: mf.to_dict() for term, mf in self.terms.items()},
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> LinguisticVariable:
        """Inverse of :meth:`to_dict`; raises ValueError on a malformed mapping."""
        if not isinstance(data, Mapping):
            raise ValueError(f"variable must be an object, got {data!r}")
        missing = {"name", "universe", "terms"} - set(data)
        if missing:
            raise ValueError(f"variable {data.get('name')!r}: missing {sorted(missing)}")
        if not isinstance(data["terms"], Mapping):
            raise ValueError(f"variable {data['name']!r}: terms must be an object")
        terms = {}
        for term, mf in data["terms"].items():
            try:
                terms[term] = membership_from_dict(mf)
            except ValueError as exc:
                raise ValueError(f"variable {data['name']!r}, term {term!r}: {exc}") from None
        universe = data["universe"]
        if not isinstance(universe, Sequence) or isinstance(universe, str) or len(universe) != 2:
            raise ValueError(f"variable {data['name']!r}: universe must be [low, high]")
        return cls(data["name"], tuple(universe), terms)
