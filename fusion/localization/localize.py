"""Multi-source localization of one processing window's TDOAs (steps 56-62).

:class:`MultiSourceLocalizer` takes a window's validated TDOAs and cross-pair association and
returns every source it finds as a :class:`SourceFix` (position, ``gtsam.Marginals``
covariance, the TDOAs it uses, observability flags). Four methods, for use and comparison:

``"competition"`` (default)
    Association-weighted volume (eq. 18; eq. 17 when the window has no ``alpha``) over the
    search region, its local maxima as candidates, and the candidates competing for the TDOAs
    on factor graphs (:func:`fusion.localization.competition.compete`, eq. 19-22). TDOAs the
    survivors leave to clutter that still form associated groups able to fix a source (two
    whales the coarse surface merged into one peak) get a surface of their own and new
    candidates, and all compete again (``max_rounds``). Each survivor is then re-solved with
    its EM weights (``polish``), which makes it the weighted least-squares fit of the TDOAs it
    owns; its covariance comes from the same graph.
``"eq17"`` / ``"eq18"``
    The plain surface methods: every local maximum of eq. (17) / eq. (18) above the finder's
    floor, refined coarse to fine until one TDOA sigma spans about two cells, is a source; it
    uses the TDOAs whose residual is within ``gate_sigmas``.
``"lsq"``
    One source: unweighted least squares over all TDOAs from the eq. (17) peak.

Every method drops a source using fewer than ``min_tdoas`` TDOAs or fewer than three
independent pairs (the competition counts only TDOAs associated with another of the source's
TDOAs when ``alpha`` is given), so the methods differ in how TDOAs are assigned to sources.

Observability: the position information ``J^T W J`` of the source's TDOAs gives a condition
number; a fix is flagged unobservable when it exceeds ``max_condition`` (e.g. a planar array
and a source far outside its aperture, whose depth the delays barely fix). The mirror test
re-solves from the position's mirror image through the sensors' best-fitting plane and from
its ``x, y`` at four heights, and calls the fix ambiguous when a distinct solution fits within
``mirror_chi2`` of it (the sign of ``z`` of a planar array; a second depth of a near-planar
array with few TDOAs). A clearly better solution replaces the fix; with a water column, a fix
outside it whose rival fits as well inside it is replaced, and a rival outside it is none.

Notes
-----
*Localization of Short Duration Periodic Signals*, eq. (14)-(22), paragraphs [0044]-[0049]
(steps 56-62: surfaces, depth from the volume, competing candidates).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import gtsam
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from fusion.localization.candidates import CandidateFinder
from fusion.localization.competition import (
    CompetitionSettings,
    compete,
    independent_pairs,
    supported_weights,
    vertical_starts,
)
from fusion.localization.intensity import intensity_volume, smoothing_sigma
from fusion.localization.peak_search import fine_step
from fusion.localization.search_grid import SearchGrid, SearchRegion, sensor_distances
from fusion.localization.source_fix import (
    LocalizationOutput,
    SourceFix,
    solve_weighted,
    weighted_cost,
    weighted_graph,
)
from fusion.localization.surface_paths import PathTdoas, surface_paths
from fusion.localization.window_tdoas import WindowTdoas
from fusion.types import frozen_array

__all__ = ["METHODS", "LocalizationOutput", "MultiSourceLocalizer", "SourceFix"]

_LOG = logging.getLogger(__name__)

#: 3-sigma ellipsoid of a 3-D Gaussian (chi-square, 3 degrees of freedom, 0.9973).
_CHI2_3SIGMA = 14.16

#: The localization methods of :class:`MultiSourceLocalizer`.
METHODS: tuple[str, ...] = ("competition", "eq17", "eq18", "lsq")


class MultiSourceLocalizer:
    """Localize every source of a window from its TDOAs and their cross-pair association.

    Parameters
    ----------
    method : {"competition", "eq17", "eq18", "lsq"}, keyword-only
        See the module docstring. Default ``"competition"``.
    region : SearchRegion, optional, keyword-only
        Search box and coarse grid budget (default :class:`SearchRegion()`: one array aperture
        around the sensors each way).
    finder : CandidateFinder, optional, keyword-only
        Candidate picking (default :class:`CandidateFinder()`: at most 8).
    competition : CompetitionSettings, optional, keyword-only
        Options of the competition.
    polish : bool, keyword-only
        Re-solve each competition survivor with its EM weights (default True).
    gate_sigmas : float, keyword-only
        Residual gate (in TDOA sigmas) of the TDOAs a surface peak uses (eq17/eq18).
    min_tdoas : float, keyword-only
        Smallest total TDOA weight of a reported source (default 4).
    max_condition : float, keyword-only
        Largest condition number of the position information of an observable fix.
    mirror_chi2 : float, keyword-only
        Largest rise of the weighted squared residual sum (twice the graph error) at which a
        mirrored solution still ties.
    smoothing_cells : float, keyword-only
        Delay smoothing of the surfaces in grid cells (:func:`smoothing_sigma`).
    max_rounds : int, keyword-only
        Competition rounds (default 3). After a round, each group of TDOAs left to clutter that
        are linked by ``alpha >= competition.min_alpha_link`` (all leftovers without
        ``alpha``) and could fix a source gets its own surface and candidates, and all
        candidates compete again: sources the coarse surface merged with a neighbour. Rounds
        stop as soon as no such group is left.
    surface_z : float, optional, keyword-only
        Height of the sea surface, m (0 in the project's convention). When given, every TDOA is
        also read along surface-reflected paths (:mod:`fusion.localization.surface_paths`: echoes of
        the clicks at the surface give delays between echoes and between a direct arrival and
        an echo), sources are searched below the surface only, and each fix records the path
        pair of each of its TDOAs (:attr:`SourceFix.paths`). Not used by ``"lsq"``. Default
        None: direct paths only.

    Examples
    --------
    >>> from factors.tdoa import predicted_tdoas
    >>> s = np.array([[0, 0, -900.0], [1000, 0, -1000], [0, 1000, -950], [1000, 1000, -980],
    ...               [500, 500, -1000]])
    >>> pairs = np.array([(i, j) for i in range(5) for j in range(i + 1, 5)])
    >>> taus = predicted_tdoas([300.0, 600.0, -500.0], s, pairs, c=1500.0)
    >>> loc = MultiSourceLocalizer(method="lsq", region=SearchRegion(water_column=(-1000, 0)))
    >>> out = loc.localize(s, pairs, taus, 2e-5, c=1500.0)
    >>> np.round(out.sources[0].position, 3)
    array([ 300.,  600., -500.])
    """

    def __init__(
        self,
        *,
        method: str = "competition",
        region: SearchRegion | None = None,
        finder: CandidateFinder | None = None,
        competition: CompetitionSettings | None = None,
        polish: bool = True,
        gate_sigmas: float = 3.0,
        min_tdoas: float = 3.5,
        max_condition: float = 1e6,
        mirror_chi2: float = 4.0,
        smoothing_cells: float = 1.0,
        max_rounds: int = 3,
        surface_z: float | None = None,
    ) -> None:
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
        for name, v in (("gate_sigmas", gate_sigmas), ("max_condition", max_condition),
                        ("mirror_chi2", mirror_chi2), ("smoothing_cells", smoothing_cells)):
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive and finite, got {v!r}")
        if int(max_rounds) != max_rounds or max_rounds < 1:
            raise ValueError(f"max_rounds must be a positive integer, got {max_rounds!r}")
        if not (np.isfinite(min_tdoas) and min_tdoas >= 0):
            raise ValueError(f"min_tdoas must be >= 0, got {min_tdoas!r}")
        self.method = method
        self.region = SearchRegion() if region is None else region
        self.finder = CandidateFinder() if finder is None else finder
        self.competition = CompetitionSettings() if competition is None else competition
        self.polish = bool(polish)
        self.gate_sigmas = float(gate_sigmas)
        self.min_tdoas = float(min_tdoas)
        self.max_condition = float(max_condition)
        self.mirror_chi2 = float(mirror_chi2)
        self.smoothing_cells = float(smoothing_cells)
        self.max_rounds = int(max_rounds)
        if surface_z is not None and not np.isfinite(surface_z):
            raise ValueError(f"surface_z must be finite or None, got {surface_z!r}")
        self.surface_z = None if surface_z is None else float(surface_z)
        self._grid_cache: tuple[bytes, SearchGrid, NDArray[np.float64]] | None = None

    # ------------------------------------------------------------------ entry point
    def localize(
        self,
        sensors: ArrayLike,
        pairs: ArrayLike,
        taus: ArrayLike,
        sigmas: ArrayLike,
        alpha: ArrayLike | None = None,
        *,
        c: float,
    ) -> LocalizationOutput:
        """Localize the sources of one window.

        Parameters
        ----------
        sensors : array_like, shape (n, 3)
            Sensor positions, m (z up).
        pairs : array_like of int, shape (M, 2)
            Sensor pair ``(i, j)`` of each TDOA.
        taus : array_like, shape (M,)
            Delays, arrival at ``i`` minus arrival at ``j``, s.
        sigmas : float or array_like, shape (M,)
            Delay standard deviations, s.
        alpha : array_like, shape (M, M), optional
            Cross-pair association (eq. 13): symmetric, zero diagonal. Used by
            ``"competition"`` (eq. 18 surface, eq. 21 weights, the drop rule), needed by
            ``"eq18"``, ignored by ``"eq17"`` and ``"lsq"``.
        c : float, keyword-only
            Sound speed, m/s.

        Returns
        -------
        LocalizationOutput
        """
        if np.size(taus) == 0:  # a window without validated TDOAs has no source
            return LocalizationOutput((), self.method, frozen_array(np.zeros(0)),
                                      frozen_array(np.zeros((0, 3))), 0, True)
        tdoas = WindowTdoas(sensors, np.asarray(pairs), taus,
                            np.broadcast_to(np.asarray(sigmas, dtype=float), np.shape(taus)),
                            c=c, alpha=alpha)
        if self.method == "eq18" and tdoas.alpha is None:
            raise ValueError("method 'eq18' needs the association matrix alpha")
        return self.localize_window(tdoas)

    def localize_window(self, tdoas: WindowTdoas) -> LocalizationOutput:
        """:meth:`localize` for an already checked :class:`WindowTdoas`."""
        equation = 17 if self.method in ("eq17", "lsq") or tdoas.alpha is None else 18
        real, paths = tdoas, None
        region = self._region(real.sensors)
        if self.surface_z is not None and self.method != "lsq":
            paths = surface_paths(real, self.surface_z)
            tdoas = paths.tdoas
        lo, hi = region.bounds(real.sensors)
        grid, ranges = self._coarse(region, real.sensors, tdoas.sensors)
        volume = intensity_volume(tdoas, grid, equation=equation, cells=self.smoothing_cells,
                                  distances=ranges,
                                  groups=None if paths is None else paths.measured)
        finder = self.finder
        if self.method in ("eq17", "eq18"):  # refine every peak to the fine level
            finder = CandidateFinder(max_candidates=finder.max_candidates,
                                     min_relative=finder.min_relative, footprint=finder.footprint,
                                     refine_levels=_levels_to_fine(tdoas, grid.step),
                                     refine_half=finder.refine_half,
                                     min_separation_cells=finder.min_separation_cells,
                                     scan_depth=finder.scan_depth)
        cand = finder.find(volume, tdoas, lo=lo, hi=hi)
        ctx = _Context(real, paths, region)
        if self.method == "competition":
            return self._competition(tdoas, cand.positions, cand.step, ctx)
        if self.method == "lsq":
            return self._lsq(tdoas, cand.positions, ctx)
        return self._surface_peaks(tdoas, cand.positions, ctx)  # eq17 / eq18

    def _region(self, sensors: NDArray[np.float64]) -> SearchRegion:
        """The search region, its top at the surface when surface paths are read."""
        lo, hi = self.region.bounds(sensors)
        if self.surface_z is None or hi[2] <= self.surface_z:
            return self.region
        return SearchRegion(extent_factor=self.region.extent_factor,
                            water_column=(float(min(lo[2], self.surface_z - 1.0)), self.surface_z),
                            max_points=self.region.max_points)

    def _coarse(self, region: SearchRegion, sensors: NDArray[np.float64],
                ranged: NDArray[np.float64]) -> tuple[SearchGrid, NDArray[np.float64]]:
        """The coarse grid of the array and its ranges to `ranged` (kept for the next window)."""
        key = np.asarray(ranged, dtype=float).tobytes() + np.asarray(sensors).tobytes()
        if self._grid_cache is None or self._grid_cache[0] != key:
            grid = region.volume(sensors)
            self._grid_cache = (key, grid, sensor_distances(grid, ranged))
        return self._grid_cache[1], self._grid_cache[2]

    # ------------------------------------------------------------------ methods
    def _competition(self, tdoas: WindowTdoas, starts: NDArray, step: float, ctx: _Context
                     ) -> LocalizationOutput:
        scale = float(np.max(smoothing_sigma(tdoas.sigmas, step, c=tdoas.c,
                                             cells=self.smoothing_cells)))
        if starts.shape[0] == 0:
            return self._output((), ctx.real, starts, 0, True)
        options = {"settings": self.competition, "z_range": ctx.region.water_column,
                   "groups": None if ctx.paths is None else ctx.paths.measured,
                   "surface_z": self.surface_z if ctx.paths is not None else None}
        res = compete(tdoas, starts, start_scale_s=scale, **options)
        iterations = res.iterations
        grid, ranges = self._coarse(ctx.region, ctx.real.sensors, tdoas.sensors)
        lo, hi = ctx.region.bounds(ctx.real.sensors)
        for _ in range(self.max_rounds - 1):
            groups = self._unexplained(tdoas, res.clutter, ctx)
            # sources the coarse surface merged with a neighbour: look again, one surface per
            # group of associated TDOAs no candidate explains, and let everyone compete anew
            extra = [self.finder.find(
                intensity_volume(tdoas.subset(g), grid, equation=17 if tdoas.alpha is None else 18,
                                 cells=self.smoothing_cells, distances=ranges,
                                 groups=None if ctx.paths is None else ctx.paths.measured[g]),
                tdoas.subset(g), lo=lo, hi=hi).positions for g in groups]
            extra = np.vstack(extra) if extra else np.zeros((0, 3))
            if extra.shape[0] == 0:
                break
            _LOG.debug("%d groups of unexplained associated TDOAs: %d more candidates",
                       len(groups), extra.shape[0])
            starts = np.vstack([starts, extra])
            # warm start: the survivors keep their TDOAs and scale, the newcomers share the rest
            k_old, k_new = res.positions.shape[0], extra.shape[0]
            weights = np.vstack([res.weights, np.tile(res.clutter / k_new, (k_new, 1))])
            res = compete(tdoas, np.vstack([res.positions, extra]), start_scale_s=scale,
                          weights=np.clip(weights, 0.0, 1.0),
                          settled=np.arange(k_old + k_new) < k_old, **options)
            iterations += res.iterations
        fixes = []
        for k in range(res.positions.shape[0]):
            w = res.weights[k]
            if not self._enough(tdoas, w):
                continue
            pos = res.positions[k]
            if self.polish:
                pos = solve_weighted(tdoas, pos, w)
            fixes.append(self._fix(tdoas, pos, w, ctx))
        return self._output(fixes, ctx.real, starts, iterations, res.converged)

    def _unexplained(self, tdoas: WindowTdoas, clutter: NDArray, ctx: _Context
                     ) -> list[NDArray[np.intp]]:
        """Groups of TDOAs left to clutter that could each fix a source.

        The groups are the connected components of the leftovers linked by
        ``alpha >= min_alpha_link`` (all leftovers form one group without ``alpha``); a group
        qualifies with at least ``min_tdoas`` measured TDOAs spanning three independent pairs.
        """
        left = np.flatnonzero(clutter > 0.5)
        measured = np.arange(tdoas.m) if ctx.paths is None else np.asarray(ctx.paths.measured)
        if np.unique(measured[left]).size < max(self.min_tdoas, 3):
            return []
        label = np.zeros(left.size, dtype=int)
        if tdoas.alpha is not None:
            links = np.asarray(tdoas.alpha)[np.ix_(left, left)] >= self.competition.min_alpha_link
            _, label = connected_components(csr_matrix(links), directed=False)
        pairs = np.asarray(tdoas.pairs)
        groups = []
        for g in np.unique(label):
            mask = np.zeros(tdoas.m, dtype=bool)
            mask[left[label == g]] = True
            if (np.unique(measured[mask]).size >= self.min_tdoas
                    and independent_pairs(pairs, mask) >= 3):
                groups.append(left[label == g])
        return groups

    def _surface_peaks(self, tdoas: WindowTdoas, peaks: NDArray, ctx: _Context
                       ) -> LocalizationOutput:
        fixes = []
        for p in peaks:
            w = self._gate(tdoas, p)
            if self._enough(tdoas, w, associated=False):
                fixes.append(self._fix(tdoas, p, w, ctx, mirror=False))
        return self._output(fixes, ctx.real, peaks, 0, True)

    def _lsq(self, tdoas: WindowTdoas, peaks: NDArray, ctx: _Context) -> LocalizationOutput:
        w = np.ones(tdoas.m)
        if peaks.shape[0] == 0 or independent_pairs(np.asarray(tdoas.pairs), w > 0) < 3:
            return self._output((), tdoas, peaks, 0, True)
        pos = solve_weighted(tdoas, peaks[0], w)
        return self._output([self._fix(tdoas, pos, w, ctx)], tdoas, peaks, 0, True)

    # ------------------------------------------------------------------ helpers
    def _gate(self, tdoas: WindowTdoas, p: NDArray) -> NDArray[np.float64]:
        r = tdoas.predicted(p) - tdoas.taus
        return (np.abs(r) <= self.gate_sigmas * np.asarray(tdoas.sigmas)).astype(float)

    def _enough(self, tdoas: WindowTdoas, w: NDArray, *, associated: bool = True) -> bool:
        """The drop rule: enough TDOAs spanning three independent pairs.

        With `associated` (the competition) and ``alpha``, only TDOAs associated with another
        of the fix's TDOAs count (:func:`fusion.localization.competition.supported_weights`).
        """
        alpha = tdoas.alpha if associated and self.competition.use_alpha else None
        ws = supported_weights(w, alpha, self.competition.min_alpha_link)
        return bool(ws.sum() >= self.min_tdoas
                    and independent_pairs(np.asarray(tdoas.pairs), ws > 0.5) >= 3)

    def _output(self, fixes, tdoas: WindowTdoas, starts: NDArray, iterations: int,
                converged: bool) -> LocalizationOutput:
        fixes = sorted(fixes, key=lambda f: -float(f.weights.sum()))
        owned = np.sum([f.weights for f in fixes], axis=0) if fixes else np.zeros(tdoas.m)
        return LocalizationOutput(tuple(fixes), self.method, frozen_array(np.clip(1.0 - owned, 0, 1)),
                                  frozen_array(np.asarray(starts).reshape(-1, 3)), int(iterations),
                                  bool(converged))

    def _fix(self, tdoas: WindowTdoas, pos: NDArray, w: NDArray, ctx: _Context, *,
             mirror: bool = True) -> SourceFix:
        pos = np.asarray(pos, dtype=float)
        mirror_pos = np.full(3, np.nan)
        ambiguous = False
        if mirror:
            pos, mirror_pos, ambiguous = self._mirror_test(tdoas, pos, w, ctx)
        graph, values, key = weighted_graph(tdoas, pos, w)
        a, _ = graph.linearize(values).jacobian()
        info = a.T @ a  # J^T W J, whitened
        evals = np.linalg.eigvalsh(info)
        cond = float(evals[-1] / evals[0]) if evals[0] > 0 else float("inf")
        cov = np.full((3, 3), np.nan)
        if np.isfinite(cond):
            try:
                cov = np.asarray(gtsam.Marginals(graph, values).marginalCovariance(key))
            except RuntimeError:  # indeterminant system
                _LOG.warning("Marginals failed at %s; covariance left NaN", np.round(pos, 3))
        used = w > 0.5
        r = tdoas.predicted(pos) - tdoas.taus
        rms = float(np.sqrt(np.mean(r[used] ** 2))) if np.any(used) else float("nan")
        observable = bool(cond <= self.max_condition and not ambiguous)
        weights, paths = np.asarray(w, dtype=float), None
        if ctx.paths is not None:  # per measured TDOA, with the path pair it is read along
            weights = np.minimum(ctx.paths.collapse(w), 1.0)
            paths = ctx.paths.paths_of(w)
        return SourceFix(position=pos, covariance=cov, information=info, weights=weights,
                         tdoas_used=int(np.sum(weights > 0.5)), residual_rms_s=rms,
                         condition_number=cond, observable=observable,
                         mirror_ambiguous=ambiguous, mirror_position=mirror_pos, paths=paths)

    def _mirror_test(self, tdoas: WindowTdoas, pos: NDArray, w: NDArray, ctx: _Context
                     ) -> tuple[NDArray, NDArray, bool]:
        """(position, rival position or NaN, ambiguous) after the mirror / depth test.

        Re-solves with the fix's weights from its mirror image through the sensors' plane and
        from its ``x, y`` at four heights over the search box; a distinct solution (more than
        3 sigma away by the fix's information) that fits within `mirror_chi2` is a rival.
        """
        s = np.asarray(ctx.real.sensors)
        centre = s.mean(axis=0)
        normal = np.linalg.svd(s - centre)[2][-1]  # normal of the best-fitting plane
        height = float((pos - centre) @ normal)
        lo, hi = ctx.region.bounds(s)
        starts = [pos - 2.0 * height * normal] + vertical_starts(pos, (lo[2], hi[2]))[1:]
        graph, values, _ = weighted_graph(tdoas, pos, w)
        a, _ = graph.linearize(values).jacobian()
        info = a.T @ a
        cost = weighted_cost(tdoas, pos, w)
        none = np.full(3, np.nan)
        rival: NDArray | None = None
        for start in starts:
            other = solve_weighted(tdoas, start, w, iterations=30, tol=1e-6)  # a rival, roughly
            d = other - pos
            if float(d @ info @ d) <= _CHI2_3SIGMA or not _in_water(ctx.region, other):
                continue  # the same solution, or a rival outside the water column
            rise = 2.0 * (weighted_cost(tdoas, other, w) - cost)  # chi-square rise
            if rise < -self.mirror_chi2 or (rise <= self.mirror_chi2
                                            and not _in_water(ctx.region, pos)):
                # clearly better, or the physical one: polish it and test again from there
                return self._mirror_test(tdoas, solve_weighted(tdoas, other, w), w, ctx)
            if rise <= self.mirror_chi2 and rival is None:
                rival = other
        return (pos, none, False) if rival is None else (pos, rival, True)



@dataclass(frozen=True)
class _Context:
    """One window's measured TDOAs, their path reading (or None) and the search region."""

    real: WindowTdoas
    paths: PathTdoas | None
    region: SearchRegion


def _in_water(region: SearchRegion, p: NDArray) -> bool:
    wc = region.water_column
    return wc is None or bool(wc[0] <= p[2] <= wc[1])


def _levels_to_fine(tdoas: WindowTdoas, step: float, shrink: float = 3.0) -> int:
    """Coarse-to-fine levels from `step` down to :func:`fine_step`."""
    target = fine_step(tdoas)
    return max(0, int(np.ceil(np.log(max(step, target) / target) / np.log(shrink))))
