"""The cubes the passive pipeline reads: on the scale where noise has unit mean.

The tracker's peak measurement and the TQI's amplitude assume powers whose noise has mean 1.
:func:`unit_noise_cubes` normalises a cube whose median noise level
(:func:`fusion.passive.acquisition.noise_mean_level`) is off 1 by more than
:data:`~fusion.passive.acquisition.normalise.UNIT_NOISE_TOLERANCE`, and uses one at unit noise
mean as it is -- or does what the caller decides. ``fusion passive`` calls it with its
``--normalize`` / ``--no-normalize`` (None: decided from the data).
"""

from __future__ import annotations

from collections.abc import Sequence

from fusion.passive.acquisition.normalise import (
    UNIT_NOISE_TOLERANCE,
    noise_mean_level,
    normalize_spectra,
)
from fusion.types import Cube

__all__ = ["POOL_SCANS", "normalized", "unit_noise_cubes"]

#: Scans pooled into one noise estimate (the acquisition's history).
POOL_SCANS = 60


def normalized(cube: Cube) -> Cube:
    """`cube` normalised to unit noise mean (:func:`normalize_spectra`, :data:`POOL_SCANS`)."""
    pool = min(POOL_SCANS, cube.n_scans)
    return Cube(power=normalize_spectra(cube.power, pool_scans=pool), freqs=cube.freqs,
                scan_period=cube.scan_period, aperture=cube.aperture,
                sound_speed=cube.sound_speed)


def unit_noise_cubes(cubes: Sequence[Cube], normalize: bool | None,
                     names: Sequence[str]) -> tuple[list[Cube], dict, list[str]]:
    """The cubes the tracker reads, normalised where `normalize` says or, when it is None, where
    their noise level is off unit.

    Parameters
    ----------
    cubes : sequence of Cube
        Consecutive cubes of one recording.
    normalize : bool or None
        True: normalise every cube; False: use them as read; None: decide per cube from its
        median noise level over its first :data:`POOL_SCANS` scans.
    names : sequence of str
        A name per cube (its file), for the record and the lines.

    Returns
    -------
    cubes : list of Cube
        The cubes to track on.
    record : dict
        Per name: ``normalized`` and, when decided from the data, ``noise_level``;
        ``source`` ``"estimated"`` or ``"given"``.
    lines : list of str
        One line per decision from the data (none for a given choice).
    """
    out, record, lines = [], {}, []
    for name, cube in zip(names, cubes, strict=True):
        if normalize is None:
            level = noise_mean_level(cube.power, pool_scans=POOL_SCANS)
            apply = not 1.0 / UNIT_NOISE_TOLERANCE <= level <= UNIT_NOISE_TOLERANCE
            lines.append(f"{name}: median noise level {level:.3g} -> "
                         + ("normalised to unit noise mean" if apply else
                            "already at unit noise mean, used as read")
                         + " (--normalize, --no-normalize)")
            record[str(name)] = {"normalized": apply, "noise_level": level, "source": "estimated"}
        else:
            apply = bool(normalize)
            record[str(name)] = {"normalized": apply, "source": "given"}
        out.append(normalized(cube) if apply else cube)
    return out, record, lines
