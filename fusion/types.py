"""Data types shared by the file readers and the algorithms: :class:`Table`, :class:`Cube`, and
:func:`frozen_array`, the one helper for read-only array fields of frozen dataclasses.

The algorithms take these (or their own types), never anything of :mod:`fusion.io`; the readers
of :mod:`fusion.io` return them.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["Cube", "Table", "frozen_array"]


def frozen_array(a: ArrayLike, dtype: Any = float) -> NDArray[Any]:
    """A read-only copy of `a`: the field of a frozen dataclass that nobody can change in place.

    Parameters
    ----------
    a : array_like
        Values (any shape).
    dtype : data-type, optional
        Element type of the copy (default float).

    Returns
    -------
    ndarray
        A new array with ``flags.writeable`` False; `a` itself is left as it was.

    Examples
    --------
    >>> x = frozen_array([1, 2])
    >>> x, x.flags.writeable
    (array([1., 2.]), False)
    """
    out = np.array(a, dtype=dtype)
    out.setflags(write=False)
    return out

_REAL_KINDS = "fiu"  # numpy dtype kinds of real numbers (no bool, complex, text or objects)
#: Largest cube power (1000 dB in any unit): beyond it a sum or a normalisation overflows (a cell
#: of 1e308 made a track graph indeterminate, a GTSAM traceback).
MAX_CUBE_POWER = 1e100


@dataclass(frozen=True)
class Table:
    """Columns of a CSV file, each a 1-D array of one length.

    Attributes
    ----------
    columns : dict of str to ndarray
        Column name to values (float64, int64 for integer columns, or str).
    source : str
        Where the table came from (a file path), for messages.
    """

    columns: Mapping[str, NDArray[Any]]
    source: str = "<table>"

    def __post_init__(self) -> None:
        lengths = {len(v) for v in self.columns.values()}
        if len(lengths) > 1:
            raise ValueError(f"{self.source}: columns have different lengths {sorted(lengths)}")
        object.__setattr__(self, "columns", dict(self.columns))

    def __getitem__(self, name: str) -> NDArray[Any]:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"{self.source}: no column {name!r}") from None

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    @property
    def n_rows(self) -> int:
        """Number of rows."""
        return len(self)

    def select(self, mask: ArrayLike) -> Table:
        """Rows where `mask` is true (or at the given indices), as a new table."""
        m = np.asarray(mask)
        return Table({k: v[m] for k, v in self.columns.items()}, self.source)


@dataclass(frozen=True)
class Cube:
    """Beam/frequency/time power of a line array, beams equally spaced in cosine.

    Attributes
    ----------
    power : ndarray, shape (n_scans, n_beams, n_bins)
        Power, linear, >= 0 (normalised spectra have noise mean 1).
    freqs : ndarray, shape (n_bins,)
        Bin centre frequencies, Hz, increasing.
    scan_period : float
        Time between scans, s.
    aperture : float
        Array aperture, m.
    sound_speed : float
        Sound speed, m/s.
    """

    power: NDArray[np.float64]
    freqs: NDArray[np.float64]
    scan_period: float
    aperture: float
    sound_speed: float = 1500.0

    def __post_init__(self) -> None:
        for name in ("power", "freqs"):
            dtype = np.asarray(getattr(self, name)).dtype
            if dtype.kind not in _REAL_KINDS:
                raise ValueError(f"{name} must hold real numbers, got {dtype} values")
        for name in ("scan_period", "aperture", "sound_speed"):
            v = getattr(self, name)
            if isinstance(v, bool | np.bool_) or not isinstance(v, numbers.Real):
                raise ValueError(f"{name} must be a real number, got {v!r}")
        power = np.asarray(self.power, dtype=float)
        freqs = np.asarray(self.freqs, dtype=float).reshape(-1)
        if power.ndim != 3:
            raise ValueError(f"power must have shape (scans, beams, bins), got {power.shape}")
        if power.shape[0] < 2 or power.shape[1] < 2 or power.shape[2] < 1:
            raise ValueError(f"cube too small: {power.shape} (need >= 2 scans, >= 2 beams, >= 1 bin)")
        if freqs.shape[0] != power.shape[2]:
            raise ValueError(f"{freqs.shape[0]} frequencies for {power.shape[2]} bins")
        if not (np.all(np.isfinite(power)) and np.all(np.isfinite(freqs))):
            raise ValueError("cube contains NaN or infinite values")
        if np.any(power < 0):
            raise ValueError("power has negative values")
        if power.max() > MAX_CUBE_POWER:
            where = tuple(int(i) for i in np.unravel_index(int(np.argmax(power)), power.shape))
            raise ValueError(f"power {power.max():g} at (scan, beam, bin) {where} is beyond "
                             f"{MAX_CUBE_POWER:g}, implausible (check units)")
        if freqs.size > 1 and np.any(np.diff(freqs) <= 0):
            raise ValueError("freqs must be strictly increasing")
        for name in ("scan_period", "aperture", "sound_speed"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be positive, got {v!r}")
            object.__setattr__(self, name, float(v))
        object.__setattr__(self, "power", power)
        object.__setattr__(self, "freqs", freqs)

    @property
    def n_scans(self) -> int:
        """Number of scans."""
        return int(self.power.shape[0])

    @property
    def n_beams(self) -> int:
        """Number of beams."""
        return int(self.power.shape[1])

    @property
    def n_bins(self) -> int:
        """Number of frequency bins."""
        return int(self.power.shape[2])
