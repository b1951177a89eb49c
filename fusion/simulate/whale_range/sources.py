"""The whales of the click simulator: one click train per source, propagated along every path
and rendered into the audio.

Used by :func:`fusion.simulate.clicks.simulate_clicks`. The default scenario draws only from the
scenario generator ``rng`` (in the order it always has); the range options draw from ``rng2``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.simulate.whale_range.propagation import FloorPlane, SoundSpeedProfile
from fusion.simulate.whale_range.synthesis import _positions, _render, draw_emission_times
from fusion.simulate.whale_range.types import ClickWaveform, WhaleTrack
from fusion.simulate.whale_range.world import RANGE_DEFAULTS, draw_click_band

__all__ = ["jsonable", "simulate_whales"]


def simulate_whales(
    audio: NDArray[np.float32],
    *,
    rng: np.random.Generator,
    rng2: np.random.Generator | None,
    opts: dict[str, Any],
    n_sources: int,
    centre: NDArray[np.float64],  # (2,) or (m, 2)
    radius: float,
    floor: FloorPlane | None,
    propagate: Callable[[NDArray[np.float64]], dict[str, tuple[NDArray, NDArray]]],
    loss: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    coef: dict[str, Any],
    click: ClickWaveform,
    duration_s: float,
    fs: float,
    depth_range_m: tuple[float, float],
    speed_range_mps: tuple[float, float],
    max_turn_rate_deg_s: float,
    ici_s: float,
    ici_jitter_s: float,
    level_jitter_db: float,
) -> list[WhaleTrack]:
    """Draw, propagate and render the whales (see :func:`~fusion.simulate.clicks.simulate_clicks`
    for the meaning of each option); `rng2` is None for the default scenario.

    Each whale starts within ``0.6 radius`` of `centre` (shape (2,)) or of one of the points
    `centre` (shape (m, 2)) chosen at random with `rng2` (above the floor when there is one),
    moves on an arc, clicks with gamma-distributed intervals; every path of `propagate` is
    rendered whose coefficient in `coef` is not zero.
    """
    world_on = rng2 is not None
    n_sensors = audio.shape[1]
    ici_range_s, whale_clicks = opts["ici_range_s"], opts["whale_clicks"]
    click_band_hz, click_duration_s = opts["click_band_hz"], opts["click_duration_s"]
    source_level_spread_db = opts["source_level_spread_db"]
    tracks: list[WhaleTrack] = []
    for k in range(n_sources):
        start = centre if centre.ndim == 1 else centre[int(rng2.integers(centre.shape[0]))]
        rad = 0.6 * radius * np.sqrt(rng.uniform())
        phi = rng.uniform(0.0, 2.0 * np.pi)
        xy0 = start + rad * np.array([np.cos(phi), np.sin(phi)])
        lo, hi = depth_range_m
        if floor is not None:  # keep the whole track above the floor
            margin = 30.0 + 0.2 * duration_s + np.tan(np.radians(floor.slope_deg)) * \
                speed_range_mps[1] * duration_s
            room = max(float(floor.depth_at(*xy0)) - margin, 0.5 * floor.depth_m)
            hi = min(hi, room)
            lo = min(lo, 0.5 * room)
        p0 = np.array([xy0[0], xy0[1], -rng.uniform(lo, hi)])
        speed = rng.uniform(*speed_range_mps)
        heading = rng.uniform(0.0, 2.0 * np.pi)
        turn = np.radians(rng.uniform(-max_turn_rate_deg_s, max_turn_rate_deg_s))
        vz = rng.uniform(-0.2, 0.2)
        wclick, level_db, ici_k = click, 0.0, ici_s
        if world_on:
            p0, speed, heading, turn, vz = _close_pair(
                opts, rng2, tracks, p0, speed, heading, turn, vz, floor, duration_s)
            if ici_range_s is not None:
                ici_k = float(rng2.uniform(*ici_range_s))
            if whale_clicks is not None:
                wclick = whale_clicks[k]
            elif click_band_hz is not None:
                f0, f1, dur = draw_click_band(rng2, click_band_hz, click_duration_s)
                wclick = ClickWaveform(f0, f1, dur)
            if source_level_spread_db:
                level_db = float(rng2.uniform(-source_level_spread_db, source_level_spread_db))
        # start the train early enough that the slowest path at t = 0 is already arriving
        head_start_s = max(float(t.max()) for t, _ in propagate(p0[None, :]).values()) \
            + wclick.duration_s
        t_em = draw_emission_times(
            ici_mean_s=ici_k, ici_jitter_s=ici_jitter_s, t_start_s=-head_start_s - ici_k,
            t_end_s=duration_s, rng=rng,
        )
        pos = _positions(t_em, p0, speed, heading, turn, vz)
        paths = propagate(pos)
        times = {name: t_em[:, None] + t for name, (t, _) in paths.items()}
        # keep emissions with any arrival overlapping the audio (every path with a world)
        first, last = times["direct"].min(axis=1), times["direct"].max(axis=1)
        for name in times:
            if name != "direct" and (world_on or np.any(coef[name] != 0)):
                first = np.minimum(first, times[name].min(axis=1))
                last = np.maximum(last, times[name].max(axis=1))
        half = 0.5 * wclick.duration_s
        keep = (last + half > 0.0) & (first - half < duration_s)
        t_em, pos = t_em[keep], pos[keep]
        times = {name: t[keep] for name, t in times.items()}
        lengths = {name: length[keep] for name, (_, length) in paths.items()}
        src_amp = 10.0 ** (level_jitter_db * rng.standard_normal(t_em.size) / 20.0)
        if level_db:
            src_amp = src_amp * 10.0 ** (level_db / 20.0)
        amps = {"direct": src_amp[:, None] * loss(lengths["direct"])}
        for name in times:
            if name != "direct":
                amps[name] = coef[name] * src_amp[:, None] * loss(lengths[name])
        ch = np.broadcast_to(np.arange(n_sensors), times["direct"].shape).ravel()
        for name in times:
            if name == "direct" or np.any(coef[name] != 0):
                _render(audio, times[name].ravel(), ch, amps[name].ravel(), wclick.evaluate,
                        half, half, fs)
        extra = {}
        if world_on:
            extra = dict(
                bottom_echo_arrival_times=times.get("bottom"),
                bottom_echo_amplitudes=amps.get("bottom"), click=wclick,
                source_level_db=level_db,
                effective_speeds={name: lengths[name] / (times[name] - t_em[:, None])
                                  for name in times},
            )
        tracks.append(WhaleTrack(
            source_id=k, start_position=p0, speed_mps=float(speed), heading_rad=float(heading),
            turn_rate_rad_s=float(turn), vertical_rate_mps=float(vz), ici_mean_s=float(ici_k),
            ici_jitter_s=float(ici_jitter_s), emission_times=t_em, positions=pos,
            source_amplitudes=src_amp, arrival_times=times["direct"],
            arrival_amplitudes=amps["direct"], echo_arrival_times=times["surface"],
            echo_amplitudes=amps["surface"], **extra,
        ))

    return tracks


def _close_pair(opts: dict[str, Any], rng2: np.random.Generator, tracks: list[WhaleTrack],
                p0: NDArray[np.float64], speed: float, heading: float, turn: float, vz: float,
                floor: FloorPlane | None, duration_s: float) -> tuple[Any, ...]:
    """With probability ``close_pair_probability``, move a new whale's start to a distance
    drawn from ``close_pair_distance_m`` of an earlier whale and let it travel with it
    (heading within ~15 deg, speed within 10 %, same turn and vertical rates)."""
    p = opts["close_pair_probability"] or 0.0
    draw = rng2.uniform(size=11)  # fixed count: later draws do not depend on the outcome
    if not tracks or draw[0] >= p:
        return p0, speed, heading, turn, vz
    mate = tracks[int(draw[1] * len(tracks))]
    lo, hi = opts["close_pair_distance_m"] or RANGE_DEFAULTS["close_pair_distance_m"]
    dist = lo + (hi - lo) * draw[2]
    u = np.sqrt(-2.0 * np.log(draw[3:6])) * np.cos(2.0 * np.pi * draw[6:9])  # 3 normals
    u[2] *= 0.5
    u /= np.linalg.norm(u)
    new = mate.start_position + dist * u
    if floor is not None and -new[2] > float(floor.depth_at(*new[:2])) - 30.0 - 0.2 * duration_s:
        new = mate.start_position + dist * u * np.array([1.0, 1.0, -1.0])
    new[2] = min(new[2], -10.0)
    return (new, mate.speed_mps * (0.9 + 0.2 * draw[9]), mate.heading_rad + 0.5 * (draw[10] - 0.5),
            mate.turn_rate_rad_s, mate.vertical_rate_mps)


def jsonable(opts: dict[str, Any]) -> dict[str, Any]:
    """The range options as JSON values (profiles and clicks as dicts)."""
    out: dict[str, Any] = {}
    for k, v in opts.items():
        if isinstance(v, SoundSpeedProfile):
            v = v.to_dict()
        elif k == "whale_clicks" and v is not None:
            v = [{"f_start_hz": c.f_start_hz, "f_end_hz": c.f_end_hz, "duration_s": c.duration_s}
                 for c in v]
        elif isinstance(v, tuple):
            v = list(v)
        out[k] = v
    return out


