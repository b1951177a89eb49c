"""The bottom-mounted-range world of the click simulator: hydrophones on a sloping sea floor,
surveyed positions with errors, per-sensor reflection coefficients, per-whale click shapes and
interfering broadband clicks of other species.

Used by :func:`fusion.simulate.clicks.simulate_clicks` when any of its range options is given;
none of it is drawn otherwise (the default scenario is unchanged). Every draw here comes from the
scenario's second generator, ``default_rng([seed, 1])``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.simulate.whale_range.propagation import FloorPlane, SoundSpeedProfile

__all__ = ["InterfererTrain", "RangeWorld", "broadband_click", "grid_layout"]

#: Defaults of the range options when the range world is on but an option is not given.
RANGE_DEFAULTS: dict[str, Any] = {
    "floor_depth_m": 1600.0,
    "floor_slope_deg": 0.0,
    "height_above_floor_m": (1.0, 20.0),
    "bottom_reflection_db": (-15.0, -3.0),
    "bottom_reflection_sign": "positive",
    "close_pair_distance_m": (20.0, 100.0),
    "interferer_ici_s": (0.05, 1.0),
    "interferer_duration_s": (20e-6, 80e-6),
    "interferer_level_db": (-6.0, 6.0),
    "interferer_freq_hz": (15_000.0, 40_000.0),
}




@dataclass(frozen=True)
class InterfererTrain:
    """Broadband clicks of a non-target source (another species) at a fixed position.

    Attributes
    ----------
    source_id : int
        Index among the interferers (not among the whales).
    position : ndarray, shape (3,)
        Position, m.
    ici_mean_s, ici_jitter_s : float
        Inter-click interval mean and standard deviation, s.
    duration_s : float
        Click length, s (Gaussian envelope, ``sigma = duration / 6``).
    centre_freq_hz : float
        Carrier of the broadband click, Hz.
    level_db : float
        Source level relative to a nominal whale click, dB.
    emission_times : ndarray, shape (n,)
    arrival_times, arrival_amplitudes : ndarray, shape (n, n_sensors)
        Direct path (click centre times, peak amplitudes).
    echo_arrival_times, echo_amplitudes : ndarray, shape (n, n_sensors)
        Surface echo.
    bottom_echo_arrival_times, bottom_echo_amplitudes : ndarray, shape (n, n_sensors) or None
        Sea-floor echo (None without a floor).
    """

    source_id: int
    position: NDArray[np.float64]
    ici_mean_s: float
    ici_jitter_s: float
    duration_s: float
    centre_freq_hz: float
    level_db: float
    emission_times: NDArray[np.float64]
    arrival_times: NDArray[np.float64]
    arrival_amplitudes: NDArray[np.float64]
    echo_arrival_times: NDArray[np.float64]
    echo_amplitudes: NDArray[np.float64]
    bottom_echo_arrival_times: NDArray[np.float64] | None = None
    bottom_echo_amplitudes: NDArray[np.float64] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The truth.json form."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class RangeWorld:
    """What the range options add to a scenario (``ClickScenario.world``).

    Attributes
    ----------
    echo : str
        Rendered echoes: ``none``, ``surface``, ``bottom`` or ``both``.
    nominal_sound_speed : float
        The one speed written into ``array.json`` (the profile's water-column mean, rounded to
        0.1 m/s, unless given), m/s.
    sensors_true : ndarray, shape (n_sensors, 3)
        True hydrophone positions (the audio is propagated to these), m.
    position_error_m : float
        Standard deviation per axis of the survey error (surveyed = true + error), m.
    surface_coefficients : ndarray, shape (n_sensors,)
        Signed pressure reflection coefficient of the surface echo at each sensor.
    floor : FloorPlane or None
    bottom_coefficients : ndarray, shape (n_sensors,) or None
        Signed reflection coefficient of the sea-floor echo at each sensor.
    profile : SoundSpeedProfile or None
        None: straight rays at the nominal speed (the localizer's model).
    interferers : tuple of InterfererTrain
    parameters : dict
        The range options as used (drawn per-scenario values resolved), JSON-serialisable.
    """

    echo: str
    nominal_sound_speed: float
    sensors_true: NDArray[np.float64]
    position_error_m: float
    surface_coefficients: NDArray[np.float64]
    floor: FloorPlane | None = None
    bottom_coefficients: NDArray[np.float64] | None = None
    profile: SoundSpeedProfile | None = None
    interferers: tuple[InterfererTrain, ...] = ()
    parameters: dict[str, Any] = field(default_factory=dict)

    def sensor_heights_m(self) -> NDArray[np.float64] | None:
        """Height of each true sensor above the floor plane, m (None without a floor)."""
        return None if self.floor is None else self.floor.height_above(self.sensors_true)

    def to_dict(self) -> dict[str, Any]:
        """The truth.json keys this world adds."""
        heights = self.sensor_heights_m()
        return {
            "echo": self.echo,
            "nominal_sound_speed": self.nominal_sound_speed,
            "sensors_true": self.sensors_true,
            "position_error_m": self.position_error_m,
            "floor": None if self.floor is None else self.floor.to_dict(),
            "sensor_heights_m": heights,
            "surface_reflection_coefficients": self.surface_coefficients,
            "bottom_reflection_coefficients": self.bottom_coefficients,
            "sound_speed_profile": None if self.profile is None else self.profile.to_dict(),
            "interferers": [t.to_dict() for t in self.interferers],
            "parameters": self.parameters,
        }


def grid_layout(n: int, spacing_m: float, rng: np.random.Generator) -> NDArray[np.float64]:
    """Horizontal positions of `n` hydrophones: the `n` points of a triangular lattice nearest a
    random point, jittered (12 % of the spacing), rotated at random, centred on the origin and
    scaled so that the median nearest-neighbour distance is `spacing_m`. Shape (n, 2)."""
    i, j = np.meshgrid(np.arange(-4, 5), np.arange(-4, 5))
    lattice = np.column_stack([(i + 0.5 * j).ravel(), (j * np.sqrt(3.0) / 2.0).ravel()])
    ref = rng.uniform(-0.3, 0.3, 2)
    dist = np.linalg.norm(lattice - ref, axis=1) + rng.uniform(0.0, 1e-6, lattice.shape[0])
    xy = lattice[np.argsort(dist)[:n]] + rng.normal(0.0, 0.12, (n, 2))
    a = rng.uniform(0.0, 2.0 * np.pi)
    xy = xy @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    xy -= xy.mean(axis=0)
    d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    return xy * (spacing_m / float(np.median(d.min(axis=1))))


def bottom_sensors(xy: NDArray[np.float64], floor: FloorPlane,
                   heights: NDArray[np.float64]) -> NDArray[np.float64]:
    """Hydrophones `heights` metres above the floor (along its normal) over the points `xy`."""
    on_floor = np.column_stack([xy, -floor.depth_at(xy[:, 0], xy[:, 1])])
    return on_floor + heights[:, None] * floor.normal[None, :]


def draw_click_band(rng: np.random.Generator, band_hz: tuple[float, float],
                    duration_s: tuple[float, float]) -> tuple[float, float, float]:
    """One whale's FM upsweep: start uniform in ``[lo, hi - 5 kHz]``, end uniform in
    ``[start + 5 kHz, hi]``, duration uniform in `duration_s`."""
    lo, hi = band_hz
    f0 = rng.uniform(lo, hi - 5_000.0)
    f1 = rng.uniform(f0 + 5_000.0, hi)
    return float(f0), float(f1), float(rng.uniform(*duration_s))


def broadband_click(freqs: NDArray[np.float64], durations: NDArray[np.float64]
                    ) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """Gaussian-enveloped cosine centred at ``tau = 0`` (unit peak), per event (shape (n, 1)):
    ``exp(-tau^2 / (2 sigma^2)) cos(2 pi f tau)``, ``sigma = duration / 6``, 0 outside
    ``|tau| <= duration / 2``."""

    def shape(tau: NDArray[np.float64]) -> NDArray[np.float64]:
        sigma = durations / 6.0
        env = np.exp(-0.5 * (tau / sigma) ** 2)
        return np.where(np.abs(tau) <= 0.5 * durations, env * np.cos(2 * np.pi * freqs * tau), 0.0)

    return shape


def simulate_interferers(
    audio: NDArray[np.float32],
    rng: np.random.Generator,
    *,
    n: int,
    opts: dict[str, Any],
    sensors: NDArray[np.float64],
    radius_m: float,
    floor: FloorPlane | None,
    propagate: Callable[[NDArray[np.float64]], dict[str, tuple[NDArray, NDArray]]],
    loss: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    coefficients: dict[str, NDArray[np.float64]],
    duration_s: float,
    fs: float,
) -> tuple[InterfererTrain, ...]:
    """Render `n` stationary broadband click trains (other species) into `audio` and return
    them. Each sits within `radius_m` of the array centre at a depth uniform from 20 m to 50 m
    above the floor (or 20-1000 m without a floor); ICI, click length, carrier and level are
    drawn from the ``interferer_*`` ranges of `opts` (log-uniform ICI). Every path of
    `propagate` whose coefficient is non-zero is rendered."""
    from fusion.simulate.whale_range.synthesis import _render, draw_emission_times

    out = []
    centre = sensors[:, :2].mean(axis=0)
    for k in range(n):
        rad, phi = radius_m * np.sqrt(rng.uniform()), rng.uniform(0.0, 2.0 * np.pi)
        xy = centre + rad * np.array([np.cos(phi), np.sin(phi)])
        bottom = 1000.0 if floor is None else float(floor.depth_at(xy[0], xy[1])) - 50.0
        pos = np.array([xy[0], xy[1], -rng.uniform(20.0, max(bottom, 21.0))])
        lo, hi = opts["interferer_ici_s"]
        ici = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
        dur = float(rng.uniform(*opts["interferer_duration_s"]))
        freq = float(min(rng.uniform(*opts["interferer_freq_hz"]), 0.45 * fs))
        level = float(rng.uniform(*opts["interferer_level_db"]))
        paths = propagate(pos[None, :])
        head = max(float(t.max()) for t, _ in paths.values()) + dur
        t_em = draw_emission_times(ici_mean_s=ici, ici_jitter_s=0.1 * ici,
                                   t_start_s=-head - ici, t_end_s=duration_s, rng=rng)
        t_em = t_em[t_em + head > 0.0]
        amp = 10.0 ** ((level + rng.normal(0.0, 1.0, t_em.size)) / 20.0)
        times, amps = {}, {}
        for name, (t, length) in paths.items():
            times[name] = t_em[:, None] + t
            amps[name] = amp[:, None] * loss(length) * coefficients.get(name, 1.0)
            if np.any(amps[name] != 0.0):
                ch = np.broadcast_to(np.arange(sensors.shape[0]), times[name].shape).ravel()
                shape = broadband_click(np.array([[freq]]), np.array([[dur]]))
                _render(audio, times[name].ravel(), ch, amps[name].ravel(), shape,
                        0.5 * dur, 0.5 * dur, fs)
        out.append(InterfererTrain(
            source_id=k, position=pos, ici_mean_s=ici, ici_jitter_s=0.1 * ici, duration_s=dur,
            centre_freq_hz=freq, level_db=level, emission_times=t_em,
            arrival_times=times["direct"], arrival_amplitudes=amps["direct"],
            echo_arrival_times=times["surface"], echo_amplitudes=amps["surface"],
            bottom_echo_arrival_times=times.get("bottom"), bottom_echo_amplitudes=amps.get("bottom"),
        ))
    return tuple(out)


def world_geometry(
    opts: dict[str, Any],
    *,
    n_sensors: int,
    rng: np.random.Generator,
    rng2: np.random.Generator,
    array_radius_m: float,
    sound_speed: float,
    surface_reflection: float,
) -> dict[str, Any]:
    """Floor, true and surveyed hydrophone positions and per-sensor reflection coefficients.

    With a floor (any of ``echo``, ``floor_*``, ``height_above_floor_m``, ``sensor_spacing_m``
    given) the hydrophones stand ``height_above_floor_m`` above a plane floor (missing options
    from :data:`RANGE_DEFAULTS`; the slope azimuth uniform when not given) over a
    :func:`grid_layout` of spacing ``sensor_spacing_m``, or without a spacing over the default
    ring's horizontal positions; without a floor they are on the default ring (both rings drawn
    from `rng` as in the default scenario). Surveyed = true + N(0,
    ``position_error_m``) per axis. Surface coefficients: ``-U(surface_reflection_range)`` per
    sensor, else `surface_reflection`; floor coefficients: ``10^(U(bottom_reflection_db)/20)``
    per sensor, sign positive or (``bottom_reflection_sign="random"``) random.

    The profile (``sound_speed_profile``, else None: constant `sound_speed`) gets a table
    deep enough for the array; the nominal speed is ``nominal_sound_speed``, else the
    profile's mean over the water column (floor depth at the centre, or the deepest sensor)
    rounded to 0.1 m/s, else `sound_speed`. ``echo`` defaults to ``both`` with a floor, else
    ``surface`` (``none`` when `surface_reflection` is 0).

    Returns
    -------
    dict
        ``floor, sensors_true, surveyed, surface, bottom`` (the last None without a floor),
        ``profile, nominal_sound_speed, echo, coef`` (per path: the coefficients rendered,
        zero for echoes not rendered), ``centre, radius`` (array centre and horizontal
        extent), ``whale_centres, whale_radius`` (where whales start: within ``0.6
        whale_radius`` of a random one of the centres; with a spacing the centroids of each
        sensor and its two nearest neighbours, ``0.6 whale_radius`` = half the spacing).
    """
    from fusion.simulate.whale_range.synthesis import _layout

    def opt(name: str) -> Any:
        return RANGE_DEFAULTS[name] if opts.get(name) is None else opts[name]

    has_floor = any(opts.get(k) is not None for k in (
        "echo", "floor_depth_m", "floor_slope_deg", "floor_azimuth_deg", "height_above_floor_m",
        "sensor_spacing_m"))
    floor, bottom = None, None
    if has_floor:
        azimuth = float(rng2.uniform(0.0, 360.0))
        if opts.get("floor_azimuth_deg") is not None:
            azimuth = float(opts["floor_azimuth_deg"])
        floor = FloorPlane(float(opt("floor_depth_m")), float(opt("floor_slope_deg")), azimuth)
        if opts.get("sensor_spacing_m") is None:  # the default ring, as drawn by default
            xy = _layout(n_sensors, rng, radius_m=array_radius_m)[:, :2]
        else:
            xy = grid_layout(n_sensors, float(opts["sensor_spacing_m"]), rng2)
        heights = rng2.uniform(*opt("height_above_floor_m"), n_sensors)
        true = bottom_sensors(xy, floor, heights)
    else:
        true = _layout(n_sensors, rng, radius_m=array_radius_m)
    sigma = float(opts.get("position_error_m") or 0.0)
    error = rng2.normal(0.0, 1.0, true.shape) * sigma
    surveyed = true + error if sigma > 0 else true.copy()
    if opts.get("surface_reflection_range") is not None:
        surface = -rng2.uniform(*opts["surface_reflection_range"], n_sensors)
    else:
        surface = np.full(n_sensors, float(surface_reflection))
    if floor is not None:
        bottom = 10.0 ** (rng2.uniform(*opt("bottom_reflection_db"), n_sensors) / 20.0)
        signs = rng2.choice([-1.0, 1.0], n_sensors)
        if opt("bottom_reflection_sign") == "random":
            bottom = bottom * signs
    profile, c_nominal = None, float(sound_speed)
    if opts.get("sound_speed_profile") is not None:
        sp = opts["sound_speed_profile"]
        spec = sp.to_dict() if isinstance(sp, SoundSpeedProfile) else dict(sp)
        kind = spec.pop("kind", None)
        deepest = float(-true[:, 2].min())
        span = float(np.ptp(true[:, 0]) + np.ptp(true[:, 1]))
        table = deepest + 500.0 + (0.0 if floor is None else
                                   np.tan(np.radians(floor.slope_deg)) * span)
        profile = SoundSpeedProfile(kind, spec, max_depth_m=table)
        column = floor.depth_m if floor is not None else deepest
        c_nominal = round(profile.mean_speed(column), 1)
    if opts.get("nominal_sound_speed") is not None:
        c_nominal = float(opts["nominal_sound_speed"])
    echo = opts.get("echo") or ("both" if floor is not None else
                                ("surface" if surface_reflection else "none"))
    if floor is None and echo in ("bottom", "both"):
        raise ValueError(f"echo={echo!r} needs a sea floor")
    coef = {"direct": 1.0, "surface": surface * (echo in ("surface", "both"))}
    if floor is not None:
        coef["bottom"] = bottom * (echo in ("bottom", "both"))
    centre = true[:, :2].mean(axis=0)
    radius, whale_centres, whale_radius = float(array_radius_m), centre, float(array_radius_m)
    if floor is not None:
        radius = float(np.linalg.norm(true[:, :2] - centre, axis=1).max())
    if opts.get("sensor_spacing_m") is not None:  # whales start near a sensor triplet
        d = np.linalg.norm(true[:, None, :2] - true[None, :, :2], axis=2)
        near = np.argsort(d, axis=1)[:, :3]  # each sensor and its two nearest neighbours
        whale_centres = true[near, :2].mean(axis=1)
        np.fill_diagonal(d, np.inf)
        whale_radius = float(np.median(d.min(axis=1))) / 1.2
    return {"floor": floor, "sensors_true": true, "surveyed": surveyed, "surface": surface,
            "bottom": bottom, "profile": profile, "nominal_sound_speed": c_nominal,
            "echo": echo, "coef": coef, "centre": centre, "radius": radius,
            "whale_centres": whale_centres, "whale_radius": whale_radius}
