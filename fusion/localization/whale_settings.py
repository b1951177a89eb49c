"""The localizer settings for whale clicks on hydrophones below the sea surface.

:func:`whale_localizer` builds the :class:`~fusion.localization.localize.MultiSourceLocalizer`
for clicks read along direct and surface-reflected paths; :class:`LocalizerSettings` holds the
array-independent settings of ``fusion localize`` (one option each) and gives the localizer (or
the direct-path localizer and its surface-path fallback) for an array. Chained with the click
front end by :class:`fusion.pipelines.localization.ClickLocalization`.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from fusion.localization.candidates import CandidateFinder
from fusion.localization.competition import CompetitionSettings
from fusion.localization.localize import METHODS, MultiSourceLocalizer
from fusion.localization.search_grid import SearchRegion
from fusion.localization.surface_paths import SEA_SURFACE_Z

__all__ = ["WHALE_MAX_CANDIDATES", "WHALE_MIN_TDOAS", "LocalizerSettings", "whale_localizer"]

logger = logging.getLogger(__name__)

#: Candidates per window and smallest TDOA weight of a source when surface paths are read.
WHALE_MAX_CANDIDATES = 16
WHALE_MIN_TDOAS = 5.5

def whale_localizer(
    method: str = "competition",
    *,
    surface_z: float | None = 0.0,
    bottom_z: float | None = None,
    max_candidates: int = WHALE_MAX_CANDIDATES,
    min_tdoas: float = WHALE_MIN_TDOAS,
    min_redundant_tdoas: int = 0,
    echo_ghost_lag_s: float = 0.0,
    drop_echo_only_sensors: bool = False,
) -> MultiSourceLocalizer:
    """The localizer for whale clicks on hydrophones below the sea surface.

    Parameters
    ----------
    method : str, optional
        One of :data:`fusion.localization.localize.METHODS`.
    surface_z : float or None, keyword-only
        Height of the sea surface, m (default 0, the project's convention, z up): every TDOA is
        also read along surface-reflected paths and sources are searched below the surface.
        None: direct paths only (the localizer's own defaults then apply).
    bottom_z : float, optional, keyword-only
        Height of the sea floor, m (e.g. the deepest hydrophone of a bottom-mounted array):
        the water column is then ``(bottom_z, surface_z)`` and a solution below the floor
        is none (the mirror image of a source through a near-planar bottom array).
    max_candidates : int, keyword-only
        Candidates per window (default 16: with three whales and their echoes, 8 left whales
        without a candidate on the tuning seeds).
    min_tdoas : float, keyword-only
        Smallest total TDOA weight of a source (default 5.5). Read along four path pairs, a
        set of TDOAs fits some position by chance far more often than along direct paths
        alone, and sources of 4 or 5 TDOAs were mostly such chance fits on the tuning seeds
        of ``benchmarks/bench_localize_e2e.py``; a whale heard along its echoes holds 6-30.
    min_redundant_tdoas : int, keyword-only
        Held TDOAs a source needs beyond the three unknowns of its position
        (:attr:`CompetitionSettings.min_redundant_tdoas`, default 0: off).
    echo_ghost_lag_s : float, keyword-only
        Longest echo lag of the echo-ghost test, s
        (:attr:`CompetitionSettings.echo_ghost_lag_s`, default 0: off).
    drop_echo_only_sensors : bool, keyword-only
        Drop a source that hears a sensor only through its surface echo
        (:attr:`CompetitionSettings.drop_echo_only_sensors`, default False).

    Returns
    -------
    MultiSourceLocalizer
    """
    if surface_z is None:
        region = SearchRegion() if bottom_z is None else SearchRegion(
            water_column=(float(bottom_z), 0.0))
        return MultiSourceLocalizer(method=method, region=region, competition=CompetitionSettings(
            min_redundant_tdoas=min_redundant_tdoas, echo_ghost_lag_s=echo_ghost_lag_s))
    region = SearchRegion() if bottom_z is None else SearchRegion(
        water_column=(float(bottom_z), float(surface_z)))
    return MultiSourceLocalizer(method=method, region=region, surface_z=surface_z,
                                finder=CandidateFinder(max_candidates=max_candidates),
                                min_tdoas=min_tdoas,
                                competition=CompetitionSettings(
                                    min_weight=min_tdoas, min_redundant_tdoas=min_redundant_tdoas,
                                    echo_ghost_lag_s=echo_ghost_lag_s,
                                    drop_echo_only_sensors=drop_echo_only_sensors))


@dataclass(frozen=True)
class LocalizerSettings:
    """The localization settings of ``fusion localize`` (one option each), array-independent.

    Attributes
    ----------
    method : str
        One of :data:`fusion.localization.localize.METHODS` (default ``"competition"``).
    surface_paths : bool or None
        Read every TDOA along direct and surface-reflected paths, the surface at z = 0
        (True), along direct paths only (False), or decide from the data (None, default):
        when every sensor is below the surface (z < 0, z up as in the file formats), each
        window is solved along direct paths first and read along surface paths too only when
        the direct sources leave more than ``1 - AUTO_EXPLAINED`` of its valid TDOAs
        unexplained and the surface reading explains more of them
        (:data:`fusion.pipelines.localization.AUTO_EXPLAINED`,
        :meth:`fusion.pipelines.localization.ClickLocalization.localize`); else direct paths
        with one logged line.
    sea_floor_z : float or None
        Height of the sea floor, m (z up; at or below every sensor); the search then stays in
        the water column between it and the surface. Default None: unknown.
    max_candidates : int or None
        Candidates per window. None: 16 with surface paths (:data:`WHALE_MAX_CANDIDATES`),
        the candidate finder's 8 with direct paths.
    min_source_tdoas : float or None
        Smallest total TDOA weight of a source. None: 5.5 with surface paths
        (:data:`WHALE_MIN_TDOAS`), the localizer's 3.5 with direct paths.
    min_redundant_tdoas : int
        Held TDOAs a source needs beyond the three unknowns of its position (default 0:
        off; :attr:`CompetitionSettings.min_redundant_tdoas`).
    echo_ghost_lag_s : float
        Longest echo lag of the echo-ghost test, s (default 0: off;
        :attr:`CompetitionSettings.echo_ghost_lag_s`).
    drop_echo_only_sensors : bool
        Drop a source that hears a sensor only through its surface echo (default False;
        :attr:`CompetitionSettings.drop_echo_only_sensors`).
    """

    method: str = "competition"
    surface_paths: bool | None = None
    sea_floor_z: float | None = None
    max_candidates: int | None = None
    min_source_tdoas: float | None = None
    min_redundant_tdoas: int = 0
    echo_ghost_lag_s: float = 0.0
    drop_echo_only_sensors: bool = False

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {self.method!r}")
        if self.sea_floor_z is not None and not np.isfinite(self.sea_floor_z):
            raise ValueError(f"sea_floor_z must be finite, got {self.sea_floor_z!r}")
        if self.max_candidates is not None and self.max_candidates < 1:
            raise ValueError(f"max_candidates must be >= 1, got {self.max_candidates}")
        if self.min_source_tdoas is not None and not self.min_source_tdoas > 0:
            raise ValueError(f"min_source_tdoas must be > 0, got {self.min_source_tdoas}")

    def reads_surface_paths(self, sensors: ArrayLike) -> bool:
        """Whether TDOAs are read along surface-reflected paths for these sensors (n, 3), m.

        Raises
        ------
        ValueError
            Surface paths asked for (``surface_paths=True``) or a sea floor given while a
            sensor is not below the surface.
        """
        z = np.asarray(sensors, dtype=float)[:, 2]
        below = bool(np.all(z < SEA_SURFACE_Z))
        if not below and (self.surface_paths or self.sea_floor_z is not None):
            what = "surface paths" if self.surface_paths else "a sea floor"
            raise ValueError(f"{what} need every sensor below the sea surface z = 0 (z up); "
                             f"the highest sensor is at z = {z.max():g} m")
        if self.sea_floor_z is not None and self.sea_floor_z > z.min():
            raise ValueError(f"the sea floor z = {self.sea_floor_z:g} m is above the deepest "
                             f"sensor (z = {z.min():g} m)")
        if self.surface_paths is None and not below:
            logger.warning("sensors not all below the sea surface z = 0 (highest z = %g m): "
                           "TDOAs read along direct paths only", z.max())
        return below if self.surface_paths is None else bool(self.surface_paths)

    def localizers(self, sensors: ArrayLike
                   ) -> tuple[MultiSourceLocalizer, MultiSourceLocalizer | None]:
        """The localizer for an array of sensors (n, 3), m, and the surface-path fallback.

        The fallback is None unless the paths are decided from the data (``surface_paths``
        None) for sensors all below the surface: then the first is the direct-path localizer
        and the second the surface-path one (:meth:`ClickLocalization.localize`).
        """
        below = bool(np.all(np.asarray(sensors, dtype=float)[:, 2] < SEA_SURFACE_Z))
        if self.surface_paths is None and below:
            return (dataclasses.replace(self, surface_paths=False).localizer(sensors),
                    dataclasses.replace(self, surface_paths=True).localizer(sensors))
        return self.localizer(sensors), None

    def localizer(self, sensors: ArrayLike) -> MultiSourceLocalizer:
        """The localizer of these settings for an array of sensors (n, 3), m.

        With the paths decided from the data (``surface_paths`` None), the surface-path
        localizer of sensors below the surface (see :meth:`localizers` for the pair used).
        """
        if self.reads_surface_paths(sensors):
            return whale_localizer(
                self.method, surface_z=SEA_SURFACE_Z, bottom_z=self.sea_floor_z,
                max_candidates=(WHALE_MAX_CANDIDATES if self.max_candidates is None
                                else self.max_candidates),
                min_tdoas=(WHALE_MIN_TDOAS if self.min_source_tdoas is None
                           else self.min_source_tdoas),
                min_redundant_tdoas=self.min_redundant_tdoas,
                echo_ghost_lag_s=self.echo_ghost_lag_s,
                drop_echo_only_sensors=self.drop_echo_only_sensors)
        ghosts = {"min_redundant_tdoas": self.min_redundant_tdoas,
                  "echo_ghost_lag_s": self.echo_ghost_lag_s,
                  "drop_echo_only_sensors": self.drop_echo_only_sensors}
        opts: dict = {"competition": CompetitionSettings(**ghosts)}
        if self.max_candidates is not None:
            opts["finder"] = CandidateFinder(max_candidates=self.max_candidates)
        if self.min_source_tdoas is not None:
            opts["min_tdoas"] = self.min_source_tdoas
            opts["competition"] = CompetitionSettings(min_weight=self.min_source_tdoas,
                                                      **ghosts)
        region = SearchRegion() if self.sea_floor_z is None else SearchRegion(
            water_column=(float(self.sea_floor_z), SEA_SURFACE_Z))
        return MultiSourceLocalizer(method=self.method, region=region, **opts)

    def to_dict(self) -> dict:
        """The settings as JSON-ready values."""
        return dataclasses.asdict(self)
