"""Fuzzy systems as JSON files, so that users write their own rule sets as data."""

from __future__ import annotations

import json
from pathlib import Path

from fusion.active.fuzzy.engine import FuzzySystem

__all__ = ["load_system", "save_system"]


def save_system(path: str | Path, system: FuzzySystem) -> Path:
    """Write ``system`` as JSON (atomically: temporary file, then rename).

    Parameters
    ----------
    path : str or Path
        Destination ``.json`` file.
    system : FuzzySystem

    Returns
    -------
    Path
        The written file.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(json.dumps(system.to_dict(), indent=2) + "\n", encoding="utf-8")
    tmp.replace(path)
    return path


def load_system(path: str | Path) -> FuzzySystem:
    """Read a fuzzy system written by :func:`save_system` or by hand.

    The file is a JSON object::

        {"format": "sonar-fusion fuzzy system", "version": 1,
         "variables": [{"name": "snr_db", "universe": [0, 40],
                        "terms": {"high": {"type": "right_shoulder", "a": 12, "b": 20}}}],
         "output": {"name": "rank", "universe": [0, 1], "terms": {...}},
         "rules": [{"if": {"and": [{"is": ["snr_db", "high"]},
                                   {"not": {"is": ["aspect_deg", "specular"]}}]},
                    "then": "low", "weight": 0.6}],
         "default": 0.5}

    ``format``, ``version``, ``weight``, ``default`` (null: NaN) and
    ``quad_segments`` are optional.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    FuzzySystem

    Raises
    ------
    ValueError
        Unreadable file, invalid JSON or an invalid system; the message starts
        with the file path and names the problem.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"{path}: cannot read fuzzy system ({exc.strerror or exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: invalid JSON ({exc.msg} at line {exc.lineno})") from None
    try:
        return FuzzySystem.from_dict(data)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
