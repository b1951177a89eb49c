"""A recording's sound speed from its localized windows, and the windows re-solved at it.

``fusion localize`` localizes every window at the array file's sound speed, then (by default)
reads the fixes it wrote back, estimates the one speed they share on a factor graph
(:func:`fusion.localization.sound_speed.estimate_sound_speed`) and re-solves every fix at that
speed from the TDOAs it owns (``owned_tdoas`` and ``paths`` of the ``fusion localize`` JSON). It
works on the written windows (the JSON entries of :func:`fusion.pipelines.localization.
result_document`), so it runs after the chunks of a long recording are done, in one pass to
collect the fixes and one to rewrite them.

Which fixes teach the speed: those observable and not mirror-ambiguous whose TDOAs join at
least five (real or image) sensors -- four independent delays for three coordinates (more delays
between four sensors only repeat three of them and say nothing about the speed).

By default the speed is a linear profile of depth (the speed halfway between the fixes' and the
sensors' depths and its gradient, :class:`fusion.localization.sound_speed.LinearProfile`) where
the fixes tell the gradient, every fix re-solved along straight rays through it; ``fusion
localize --no-speed-gradient`` estimates one speed (the ablation).

With ``fusion localize --sensor-position-sigma-m M`` (default 2 m) the sensors' offsets from their surveyed
positions are estimated with the chosen speed model on the same fixes
(:func:`fusion.localization.sensor_positions.estimate_sensor_positions`) and used where they fit
them significantly better (an F test against the surveyed positions on the offset parameters
the fixes determine, :data:`MIN_POSITION_F`) and explain fixes left out of their fit (a
held-out check, :data:`MAX_HELD_OUT_RATIO`); every fix is then re-solved at the refined
positions (docs/localization.md sections 22 and 24).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion.click_defaults import SENSOR_POSITION_SIGMA_M
from fusion.localization.retime import emission_shift
from fusion.localization.sensor_positions import (
    SensorPositionEstimate,
    estimate_sensor_positions,
    held_out_chi2,
    position_f,
)
from fusion.localization.sound_speed import (
    GRADIENT_PRIOR_PER_S,
    GRADIENT_SIGMA_PER_S,
    MIN_CALIBRATION_FIXES,
    FixTdoas,
    SoundSpeedEstimate,
    estimate_sound_speed,
    fix_residuals,
    path_sensors,
    refit_fix,
)
from fusion.localization.surface_paths import PATHS, SEA_SURFACE_Z
from fusion.pipelines.localization import SIGMA_FLOOR_S, UNBOUNDED_M2
from fusion.pipelines.speed_recruit import recruit

__all__ = ["SpeedCalibration", "calibrate_speed", "fix_tdoas"]

#: Sources of one window closer than this after the re-solve are one source, m (whales closer
#: than a few metres are not told apart by their delays anyway).
MERGE_M = 5.0
#: Sources of one window closer than this at the file's speed are joined to teach the speed, m
#: (a 1 % speed error moves fixes of a kilometre-scale array by tens of metres).
CLUSTER_M = 30.0
#: A teaching fix whose RMS whitened residual exceeds this many times the median is left out.
OUTLIER_RATIO = 5.0
#: Largest standard deviation of an estimated speed that is used, m/s (0.2 %): a wider one means
#: the fixes disagree on the speed (sensor positions off by metres, fixes of wrong TDOAs), and
#: re-solving at it would move every fix by an error of the same size as the one it corrects.
MAX_SIGMA_MPS = 3.0
#: Largest relative change from the file's speed that is used: the effective speeds of a sea's
#: paths differ from one value by about 1 %; a larger change is sensor positions metres off
#: (which a kilometre-scale array's delays confuse with the speed) or wrong fixes.
MAX_CHANGE = 0.015
#: Largest standard deviation of an estimated depth gradient that is used, 1/s: the prior's
#: (:data:`fusion.localization.sound_speed.GRADIENT_SIGMA_PER_S`) over sqrt(2), i.e. the fixes
#: must hold at least as much information on the gradient as the prior; a wider one is the
#: prior speaking (four-sensor fixes taught by far delays: 0.0079 1/s), and one speed is used.
MAX_GRADIENT_SIGMA_PER_S = GRADIENT_SIGMA_PER_S / np.sqrt(2.0)
#: Smallest F statistic (chi-square drop over the residual variance, one degree of freedom)
#: at which the profile replaces one speed: 9, three sigmas (p ~ 0.003) -- a constant sea
#: keeps one speed.
MIN_GRADIENT_F = 9.0
#: Standard deviation given to a recruited candidate delay, s (the validator gives none below
#: its bar; candidates of sparse trains were 0-400 us off, often under 100 us, on seeds 7703,
#: 7800, 7803).
RECRUIT_SIGMA_S = 50e-6
#: Smallest F statistic of the sensor offsets (chi-square drop per offset parameter the fixes
#: determine, over the residual variance) at which the refined positions replace the surveyed
#: ones: 9, three sigmas, as the gradient's.
MIN_POSITION_F = 9.0
#: Largest held-out chi-square ratio (offsets fitted without a fix, over surveyed positions)
#: at which the refined positions are used: the fixes left out must fit at least twice as
#: well (survey errors on the tuning seeds: 0.000-0.02; recruited far delays a survey error
#: did not bend: 339; no survey error, nothing recruited: 0.7-0.98).
MAX_HELD_OUT_RATIO = 0.5


def fix_tdoas(window: dict, source: dict, sensors: ArrayLike, c: float,
              sigma_floor_s: float = SIGMA_FLOOR_S) -> FixTdoas | None:
    """The TDOAs a written source owns, moved to its emission and read along their paths.

    Returns None for a source without ``owned_tdoas`` (a file of an older version).
    """
    owned = source.get("owned_tdoas")
    if not owned:
        return None
    s = np.asarray(sensors, dtype=float)
    d = [window["tdoas"][k] for k in owned]
    pairs = np.array([t["pair"] for t in d], dtype=np.intp)
    taus = np.array([t["tau"] for t in d], dtype=float)
    rates = np.nan_to_num(np.array([t.get("rate", 0.0) for t in d], dtype=float))
    sig = np.hypot(np.array([t["sigma"] for t in d], dtype=float), sigma_floor_s)
    paths = np.array([PATHS.index(p) for p in source.get("paths", ["direct"] * len(d))])
    pos = np.array([source["x"], source["y"], source["z"]], dtype=float)
    moved = taus + emission_shift(rates, pairs[:, 0], np.isin(paths, (1, 3)), pos, s, c,
                                  SEA_SURFACE_Z)
    s2, q2 = path_sensors(s, pairs, paths, SEA_SURFACE_Z)
    return FixTdoas(s2, q2, moved, sig, np.ones(len(d)), pos)


def _clusters(sources: list[dict]) -> list[dict]:
    """A window's sources with those within :data:`CLUSTER_M` of each other joined (their
    owned TDOAs together, the first one's position): a wrong speed splits one whale's delays
    between two nearby fixes, neither of which then spans enough sensors to teach the speed."""
    out: list[dict] = []
    for src in sources:
        if not src.get("owned_tdoas"):
            continue
        p = np.array([src["x"], src["y"], src["z"]])
        near = next((k for k, q in enumerate(out)
                     if np.linalg.norm(p - [q["x"], q["y"], q["z"]]) < CLUSTER_M), None)
        if near is None:
            out.append(src)
            continue
        q = out[near]
        out[near] = {**_joined(q, src), "observable": bool(q.get("observable", True)
                                                            or src.get("observable", True))}
    return out


def _joined(q: dict, src: dict) -> dict:
    """Source `q` holding also the TDOAs of `src` it does not hold yet (with their paths);
    mirror-ambiguous only when both were."""
    extra = [(k, h) for k, h in zip(src["owned_tdoas"], src["paths"], strict=True)
             if k not in q["owned_tdoas"]]
    return {**q, "owned_tdoas": q["owned_tdoas"] + [k for k, _ in extra],
            "paths": q["paths"] + [h for _, h in extra],
            "mirror_ambiguous": bool(q.get("mirror_ambiguous") and src.get("mirror_ambiguous"))}


def _teaches(source: dict, fix: FixTdoas | None) -> bool:
    """Whether a fix says anything about the speed: observable, not mirror-ambiguous, and
    with delays between at least 5 (real or image) sensors -- 4 independent delays for 3
    coordinates; more delays between 4 sensors only repeat 3 of them."""
    return (fix is not None and np.unique(fix.pairs).size >= 5
            and bool(source.get("observable", True))
            and not source.get("mirror_ambiguous", False))


@dataclass(frozen=True)
class SpeedCalibration:
    """The speed a recording's fixes share, and how to rewrite its windows at it.

    Attributes
    ----------
    nominal_mps : float
        The array file's speed, m/s.
    estimate : SoundSpeedEstimate or None
        The estimate; None when the recording had too few fixes to teach it (the windows are
        then left as written).
    note : str
        One line for the user: the speed used and where it came from.
    """

    nominal_mps: float
    estimate: SoundSpeedEstimate | None
    note: str
    sensors: NDArray[np.float64]
    sensor_positions: dict | None = None

    @property
    def speed_mps(self) -> float:
        """The speed the written fixes stand on, m/s."""
        return self.nominal_mps if self.estimate is None else self.estimate.speed_mps

    def record(self) -> dict:
        """What is written beside the output."""
        out = {"source": "array file" if self.estimate is None else "estimated",
               "speed_mps": self.speed_mps, "nominal_mps": self.nominal_mps}
        if self.estimate is not None:
            out.update(self.estimate.to_dict())
        if self.sensor_positions is not None:
            out["sensor_positions"] = self.sensor_positions
        return out

    def _solved(self, window: dict, src: dict) -> dict:
        """One source re-solved at the estimated speed from the TDOAs it owns."""
        fix = fix_tdoas(window, src, self.sensors, self.nominal_mps)
        if fix is None:
            return src
        c = self.estimate.profile
        p, cov = refit_fix(fix, c, variance_factor=self.estimate.variance_factor)
        finite = bool(np.all(np.isfinite(cov)))
        return {**src, "x": float(p[0]), "y": float(p[1]), "z": float(p[2]),
                "cov": np.where(np.isfinite(cov), cov, UNBOUNDED_M2).tolist(),
                "tdoas_used": int(fix.m),
                "observable": bool(src.get("observable", True)) and finite,
                "residual_rms_s": float(np.sqrt(np.mean(fix_residuals(fix, p, c) ** 2)))}

    def apply(self, window: dict) -> dict:
        """The window with each source re-solved at the estimated speed (a new dict).

        Sources that land within :data:`MERGE_M` of one another are one source that the
        wrong speed had split (each part of its TDOAs fitting its own position): they are
        merged, the stronger one (more TDOAs) taking the other's TDOAs, and solved again.
        """
        if self.estimate is None or not window.get("sources"):
            return window
        solved = [self._solved(window, src) for src in window["sources"]]
        rank = sorted(range(len(solved)), key=lambda k: -len(solved[k].get("owned_tdoas", ())))
        kept: list[dict] = []
        first: list[int] = []  # the written position of each kept source
        for k in rank:
            src = solved[k]
            p = np.array([src["x"], src["y"], src["z"]])
            near = next((k for k, q in enumerate(kept) if src.get("owned_tdoas")
                         and q.get("owned_tdoas")
                         and np.linalg.norm(p - [q["x"], q["y"], q["z"]]) < MERGE_M), None)
            if near is None:
                kept.append(src)
                first.append(k)
                continue
            first[near] = min(first[near], k)
            kept[near] = self._solved(window, _joined(kept[near], src))
        return {**window, "sources": [kept[j] for j in np.argsort(first, kind="stable")]}


def _far_candidates(window: dict, src: dict, fix: FixTdoas, sensors: NDArray[np.float64],
                     c: float) -> FixTdoas | None:
    """The candidate delays (valid or not, owned by no source) of `window` between the four
    sensors of a direct-path, observable, unambiguous fix and a sensor it does not use, moved
    to its emission like its own (sigma :data:`RECRUIT_SIGMA_S`); None when there are none."""
    n = len(sensors)
    if (not src.get("observable", True) or src.get("mirror_ambiguous", False)
            or np.unique(fix.pairs).size != 4 or np.any(fix.pairs >= n)):
        return None
    used = set(np.unique(fix.pairs).tolist())
    owned = {k for q in window.get("sources", []) for k in q.get("owned_tdoas", [])}
    idx = [k for k, d in enumerate(window["tdoas"])
           if k not in owned and (d["pair"][0] in used) != (d["pair"][1] in used)]
    if not idx:
        return None
    cand = fix_tdoas(window, {**src, "owned_tdoas": idx, "paths": ["direct"] * len(idx)},
                     sensors, c)
    return None if cand is None else FixTdoas(
        cand.sensors, cand.pairs, cand.taus, np.full(cand.m, RECRUIT_SIGMA_S), cand.weights,
        cand.position)


def calibrate_speed(windows: Iterable[dict], sensors: ArrayLike, nominal_mps: float,
                    *, recruit_far: bool = True, gradient: bool = True,
                    sensor_sigma_m: float = SENSOR_POSITION_SIGMA_M) -> SpeedCalibration:
    """Estimate the speed shared by the fixes of written windows (see the module docstring).

    Parameters
    ----------
    windows : iterable of dict
        The ``fusion localize`` JSON entries of one recording's windows.
    sensors : array_like, shape (n, 3)
        Sensor positions, m.
    nominal_mps : float
        The array file's speed, m/s.
    recruit_far : bool
        When fewer than :data:`MIN_CALIBRATION_FIXES` fixes span five sensors, recruit the
        candidate delays of a sensor the four-sensor fixes do not use where the windows agree
        on the speed they imply (:mod:`fusion.pipelines.speed_recruit`); False: only the fixes'
        own delays (``fusion localize --no-far-delays``, the ablation).
    gradient : bool
        Estimate the speed's depth gradient beside it (a linear profile); False: one speed
        (``fusion localize --no-speed-gradient``, the ablation).
    sensor_sigma_m : float
        Standard deviation of the array file's sensor positions per axis, m: above 0 the
        sensors' offsets are estimated with the speed on one graph and used where they fit the
        fixes significantly better and explain fixes left out of their fit (:func:`_refined`;
        default :data:`fusion.click_defaults.SENSOR_POSITION_SIGMA_M`, ``fusion localize``'s);
        0: the file's positions are exact.
    """
    s = np.asarray(sensors, dtype=float)
    fixes = []
    four: list[tuple[int, FixTdoas, FixTdoas]] = []  # four-sensor fixes, their far candidates
    for k, w in enumerate(windows):
        for src in _clusters(w.get("sources", [])):
            fix = fix_tdoas(w, src, s, nominal_mps)
            if _teaches(src, fix):
                fixes.append(fix)
            elif recruit_far and fix is not None:
                cand = _far_candidates(w, src, fix, s, nominal_mps)
                if cand is not None:
                    four.append((k, fix, cand))
    recruited = 0
    if len(fixes) < MIN_CALIBRATION_FIXES and four:
        more, _ = recruit(four, nominal_mps)
        if len(fixes) + len(more) >= MIN_CALIBRATION_FIXES:
            fixes, recruited = fixes + more, len(more)
    if len(fixes) < MIN_CALIBRATION_FIXES:
        return SpeedCalibration(nominal_mps, None, (
            f"sound speed: the array file's {nominal_mps:g} m/s ({len(fixes)} fixes with delays "
            f"between 5 or more sensors; {MIN_CALIBRATION_FIXES} are needed to estimate it)"), s)
    gradient_note = ""
    try:
        est, kept = _fit(fixes, nominal_mps, len(s), gradient=False)
        why = _refusal(est, nominal_mps)
        used = kept
        if gradient and recruited:
            gradient_note = ("; its depth gradient not estimated: the far delays were "
                             "recruited by one speed's consensus")
        elif gradient:  # the profile where the fixes tell its gradient, else the one speed
            try:
                prof, kept_g = _fit(fixes, nominal_mps, len(s), gradient=True)
                same = est if len(kept_g) == len(kept) else estimate_sound_speed(
                    kept_g, nominal_mps=nominal_mps)  # one speed on the same fixes
                why_g = _refusal(prof, nominal_mps) or _gradient_refusal(prof, same)
            except (ValueError, RuntimeError) as e:
                why_g = f"not estimated: {e}"
            if why_g is None:
                est, why, used = prof, None, kept_g
            else:
                gradient_note = f"; its depth gradient not used: {why_g}"
                if why is None:  # what one speed leaves out: the two models' difference
                    gradient_note += (f" (the profile's speed there differs from the one speed "
                                      f"by {abs(prof.speed_mps - est.speed_mps):.2g} m/s)")
        refined = _refined(used, s, nominal_mps, sensor_sigma_m, est) if sensor_sigma_m > 0 \
            else None
        if refined is not None and not isinstance(refined, str):
            (refined, f_pos, held), why = refined, None
            est = refined.speed
        if why is not None:
            return SpeedCalibration(nominal_mps, None, (
                f"sound speed: the array file's {nominal_mps:g} m/s ({why})"
                + (f"; {refined}" if refined else "")), s)
    except ValueError as e:
        return SpeedCalibration(nominal_mps, None, (
            f"sound speed: the array file's {nominal_mps:g} m/s (not estimated: {e})"), s)
    except RuntimeError:  # gtsam: indeterminate system
        return SpeedCalibration(nominal_mps, None, (
            f"sound speed: the array file's {nominal_mps:g} m/s (not estimated: the "
            f"{len(fixes)} fixes do not constrain it)"), s)
    if isinstance(refined, SensorPositionEstimate):
        return SpeedCalibration(nominal_mps, est, (
            f"sound speed: {_described(est)} and sensor positions estimated together from "
            f"{est.n_tdoas} TDOAs of {est.n_fixes} fixes (they fit them better than the "
            f"array file's: F = {f_pos:.3g} >= {MIN_POSITION_F:g} with {refined.n_determined:.2g} "
            f"offset parameters determined; fixes left out fit them too: held-out chi-square "
            f"ratio {held:.2g} <= {MAX_HELD_OUT_RATIO:g}); every fix re-solved at them; "
            + _positions_line(refined, s)), refined.positions(s), refined.to_dict(s))
    return SpeedCalibration(nominal_mps, est, (
        f"sound speed: {_described(est)} estimated from "
        f"{est.n_tdoas} TDOAs of {est.n_fixes} fixes"
        + (f" ({recruited} with a far sensor's delays recruited)" if recruited else "")
        + f" (array file {nominal_mps:g} m/s); every "
        "fix re-solved at it (--sound-speed array keeps the file's)" + gradient_note
        + (f"; {refined}" if refined else "")), s)


def _fit(fixes: list[FixTdoas], nominal_mps: float, n_sensors: int, *, gradient: bool
         ) -> tuple[SoundSpeedEstimate, list[FixTdoas]]:
    """The estimate from `fixes`, and the fixes it rests on: a fix that fits far worse than
    the others (a cluster of two whales, a wrong association) is left out and the speed
    estimated again."""
    est = estimate_sound_speed(fixes, nominal_mps=nominal_mps, n_real_sensors=n_sensors,
                               gradient=gradient)
    rms = np.array([np.sqrt(np.mean((fix_residuals(f, p, est.profile) / f.sigmas) ** 2))
                    for f, p in zip(fixes, est.positions, strict=True)])
    good = rms <= OUTLIER_RATIO * max(np.median(rms), 1.0)
    if not good.all() and good.sum() >= MIN_CALIBRATION_FIXES:
        kept = [f for f, g in zip(fixes, good, strict=True) if g]
        return estimate_sound_speed(kept, nominal_mps=nominal_mps, n_real_sensors=n_sensors,
                                    gradient=gradient), kept
    return est, list(fixes)


def _refusal(est: SoundSpeedEstimate, nominal_mps: float) -> str | None:
    """Why the estimate is not used (None: it is)."""
    if abs(est.speed_mps - nominal_mps) > MAX_CHANGE * nominal_mps:
        return (f"the fixes point to {est.speed_mps:.1f} m/s, more than {100 * MAX_CHANGE:g} % from "
                "it: a sea's paths differ from one speed by about 1 %; sensor positions off, "
                "or fixes of wrong TDOAs")
    if not est.sigma_mps <= MAX_SIGMA_MPS:
        return (f"the fixes disagree: {est.speed_mps:.1f} +- {est.sigma_mps:.2g} m/s from "
                f"{est.n_fixes} fixes, residuals {np.sqrt(est.variance_factor):.3g} x the "
                "TDOA sigmas; sensor positions off, or fixes of wrong TDOAs")
    return None


def _gradient_refusal(est: SoundSpeedEstimate, one: SoundSpeedEstimate) -> str | None:
    """Why an estimated depth gradient is not used: the fixes do not tell it (its standard
    deviation above :data:`MAX_GRADIENT_SIGMA_PER_S`), or it does not fit them better than
    the one speed `one` on the same fixes (an F test of the nested models: the drop of the
    chi-square over the profile's residual variance below :data:`MIN_GRADIENT_F`), or it lies
    more than three prior sigmas from the prior (a gradient no sea has between whales and
    sensors: 0.125 1/s from 3 whales' fixes on tuning seed 7900)."""
    if not est.gradient_sigma_per_s <= MAX_GRADIENT_SIGMA_PER_S:
        return (f"{est.gradient_per_s:.4f} +- {est.gradient_sigma_per_s:.2g} 1/s, the fixes "
                "do not tell it")
    if abs(est.gradient_per_s - GRADIENT_PRIOR_PER_S) > 3.0 * GRADIENT_SIGMA_PER_S:
        return (f"{est.gradient_per_s:.4f} 1/s, more than three prior sigmas from the sea's "
                f"{GRADIENT_PRIOR_PER_S:g} 1/s (fixes of wrong TDOAs)")
    dof = max(1, est.n_tdoas - 3 * est.n_fixes - 2)
    dof_one = max(1, one.n_tdoas - 3 * one.n_fixes - 1)
    drop = (one.chi2 / dof_one) * dof - est.chi2  # one speed's chi2 on the profile's dof
    f = drop / max(est.chi2 / dof, 1.0)
    if not f >= MIN_GRADIENT_F:
        return (f"{est.gradient_per_s:.4f} +- {est.gradient_sigma_per_s:.2g} 1/s fits no "
                f"better than one speed (F = {f:.3g} < {MIN_GRADIENT_F:g})")
    return None


def _described(est: SoundSpeedEstimate) -> str:
    """The estimate in words, with its standard deviation."""
    if not np.isfinite(est.gradient_sigma_per_s):
        return f"{est.speed_mps:.1f} +- {est.sigma_mps:.2g} m/s"
    return (f"{est.speed_mps:.1f} +- {est.sigma_mps:.2g} m/s at {est.reference_depth_m:.0f} m "
            f"depth (halfway between the fixes and the sensors), gradient "
            f"{est.gradient_per_s:.4f} +- {est.gradient_sigma_per_s:.2g} 1/s")


def _refined(fixes: list[FixTdoas], sensors: NDArray[np.float64], nominal_mps: float,
             sigma_m: float, without: SoundSpeedEstimate
             ) -> tuple[SensorPositionEstimate, float, float] | str:
    """The sensors' offsets estimated with the speed model of `without` on its fixes, or why
    the surveyed positions are kept: the offsets do not fit the fixes better than the survey
    (F below :data:`MIN_POSITION_F`, counting the offset parameters the fixes determine: a
    whale that barely moves leaves them unobservable), or offsets fitted without a fix do
    not explain its delays (:func:`fusion.localization.sensor_positions.held_out_chi2` above
    :data:`MAX_HELD_OUT_RATIO`: not an error every fix shares),
    or the speed estimated with them is more than :data:`MAX_CHANGE` from the file's."""
    grad = bool(np.isfinite(without.gradient_sigma_per_s))
    try:
        est = estimate_sensor_positions(fixes, n_real=len(sensors), nominal_mps=nominal_mps,
                                        sigma_m=sigma_m,
                                        d_ref=without.reference_depth_m if grad else None)
    except (ValueError, RuntimeError) as e:
        return f"sensor positions: the array file's (not estimated: {e})"
    f = position_f(est, without)
    if not f >= MIN_POSITION_F:
        return (f"sensor positions: the array file's (offsets of up to "
                f"{np.max(np.abs(est.offsets)):.2g} m fit the fixes no better: "
                f"F = {f:.3g} < {MIN_POSITION_F:g} with {est.n_determined:.2g} offset "
                "parameters determined; the fixes do not tell them)")
    try:
        with_, surveyed = held_out_chi2(fixes, n_real=len(sensors), nominal_mps=nominal_mps,
                                        sigma_m=sigma_m,
                                        d_ref=without.reference_depth_m if grad else None)
    except (ValueError, RuntimeError) as e:
        return f"sensor positions: the array file's (held-out check failed: {e})"
    ratio = with_ / max(surveyed, 1e-300)
    if not ratio <= MAX_HELD_OUT_RATIO:
        return (f"sensor positions: the array file's (offsets fitted without a fix explain "
                f"it no better: held-out chi-square {surveyed:.3g} -> {with_:.3g}, ratio "
                f"{ratio:.3g} > {MAX_HELD_OUT_RATIO:g}; not a survey error shared by the fixes)")
    # only the change is checked: with the sensors free, the speed trades against the array's
    # scale (a wide sigma the fixes' covariances hold), so its sigma says nothing of the fixes
    if abs(est.speed.speed_mps - nominal_mps) > MAX_CHANGE * nominal_mps:
        return (f"sensor positions: the array file's (with them the fixes point to "
                f"{est.speed.speed_mps:.1f} m/s, more than {100 * MAX_CHANGE:g} % from it)")
    return est, f, ratio


def _positions_line(est: SensorPositionEstimate, surveyed: NDArray[np.float64]) -> str:
    """The refined positions with their standard deviations, m."""
    parts = [f"{q}: ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) +- "
             f"({sg[0]:.2g}, {sg[1]:.2g}, {sg[2]:.2g}) m"
             for q, (p, sg) in enumerate(zip(est.positions(surveyed), est.sigmas, strict=True))]
    return ("sensor positions (prior +- " + f"{est.sigma_m:g} m from the array file): "
            + "; ".join(parts))
