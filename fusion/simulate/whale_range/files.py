"""Files of a simulated click scenario: the ``truth.json`` document and the writer of
``audio.flac``, ``array.json``, ``truth.json`` and ``tdoa_labels.csv``.

Importable from :mod:`fusion.simulate.clicks` too.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from fusion.io import (
    write_array,
    write_audio,
    write_json,
    write_table,
)
from fusion.simulate.whale_range.types import ClickScenario

__all__ = ["FILE_PEAK", "truth_document", "write_click_scenario"]

logger = logging.getLogger(__name__)

#: Peak level the written FLAC file is scaled to (headroom below the 24-bit full scale of 1).
FILE_PEAK = 0.5
#: Most channels a FLAC stream holds; more sensors are written as 24-bit WAV (``audio.wav``).
FLAC_MAX_CHANNELS = 8


def truth_document(scenario: ClickScenario, *, audio_scale: float = 1.0,
                   parameters: dict[str, Any] | None = None) -> dict[str, Any]:
    """The ground truth of a scenario as a JSON-serialisable dict (the ``truth.json`` layout).

    Parameters
    ----------
    scenario : ClickScenario
        The scenario.
    audio_scale : float, optional
        Factor from scenario units to the samples of the written audio file.
    parameters : dict, optional
        Settings the scenario was drawn with (``fusion simulate clicks --vary``), written as
        ``parameters`` (then the range options as used go to ``range_options``).

    Returns
    -------
    dict
        Keys ``kind, seed, fs, duration_s, sound_speed, audio_scale, snr_db, reference_range_m,
        noise_std_band, noise_std, noise_band_hz, absorption_db_per_km, surface_reflection,
        click, pairs, sources, transients``. Each source holds ``emission_times`` (n,),
        ``positions`` (n, 3), ``arrival_times``/``echo_arrival_times`` (n, n_sensors),
        ``arrival_amplitudes``/``echo_amplitudes`` (n, n_sensors) and ``tdoas`` (n, n_pairs:
        ``t_i - t_j`` for each pair of ``pairs``, direct path). Amplitudes are in scenario
        units; multiply by ``audio_scale`` for file units. ``snr_db`` is ``null`` for
        noise-free audio.

        A scenario with a range world (:class:`~fusion.simulate.whale_range.world.RangeWorld`) adds
        its keys (``echo, nominal_sound_speed, sensors_true, position_error_m, floor,
        sensor_heights_m, surface_reflection_coefficients, bottom_reflection_coefficients,
        sound_speed_profile, interferers, parameters``) and per source ``click``,
        ``source_level_db``, ``bottom_echo_arrival_times``/``bottom_echo_amplitudes`` and
        ``effective_speeds`` (per path, length over travel time). ``sound_speed`` is then the
        nominal speed of ``array.json``; ``tdoas`` and arrival times are those of the true
        positions and propagation. The default scenario's document has none of these keys.
    """
    pairs = scenario.pairs()
    sources = []
    for s in scenario.sources:
        sources.append({
            "id": s.source_id,
            "start_position": s.start_position,
            "speed_mps": s.speed_mps,
            "heading_rad": s.heading_rad,
            "turn_rate_rad_s": s.turn_rate_rad_s,
            "vertical_rate_mps": s.vertical_rate_mps,
            "ici_mean_s": s.ici_mean_s,
            "ici_jitter_s": s.ici_jitter_s,
            "emission_times": s.emission_times,
            "positions": s.positions,
            "source_amplitudes": s.source_amplitudes,
            "arrival_times": s.arrival_times,
            "arrival_amplitudes": s.arrival_amplitudes,
            "echo_arrival_times": s.echo_arrival_times,
            "echo_amplitudes": s.echo_amplitudes,
            "tdoas": s.tdoas(pairs),
        })
        if scenario.world is not None:
            sources[-1] |= {
                "click": {"f_start_hz": s.click.f_start_hz, "f_end_hz": s.click.f_end_hz,
                          "duration_s": s.click.duration_s},
                "source_level_db": s.source_level_db,
                "bottom_echo_arrival_times": s.bottom_echo_arrival_times,
                "bottom_echo_amplitudes": s.bottom_echo_amplitudes,
                "effective_speeds": s.effective_speeds,
            }
    doc = {
        "kind": "clicks",
        "seed": scenario.seed,
        "fs": scenario.fs,
        "duration_s": scenario.duration_s,
        "sound_speed": scenario.sensors.sound_speed,
        "audio_scale": float(audio_scale),
        "snr_db": scenario.snr_db if np.isfinite(scenario.snr_db) else None,
        "reference_range_m": scenario.reference_range_m,
        "noise_std_band": scenario.noise_std_band,
        "noise_std": scenario.noise_std,
        "noise_band_hz": list(scenario.noise_band_hz),
        "absorption_db_per_km": scenario.absorption_db_per_km,
        "surface_reflection": scenario.surface_reflection,
        "click": {
            "f_start_hz": scenario.click.f_start_hz,
            "f_end_hz": scenario.click.f_end_hz,
            "duration_s": scenario.click.duration_s,
            "taper": "hann",
        },
        "pairs": [list(p) for p in pairs],
        "sources": sources,
        "transients": [
            {"time": float(t), "channel": int(ch), "amplitude": float(a), "freq_hz": float(f)}
            for t, ch, a, f in zip(
                scenario.transient_times, scenario.transient_channels,
                scenario.transient_amplitudes, scenario.transient_freqs_hz, strict=True,
            )
        ],
    }
    if scenario.world is not None:
        world = scenario.world.to_dict()
        if parameters is not None:
            world["range_options"] = world.pop("parameters")
        doc |= world
    if parameters is not None:
        doc["parameters"] = parameters
    return doc


def write_click_scenario(out_dir: Path | str, scenario: ClickScenario, *,
                         parameters: dict[str, Any] | None = None) -> list[Path]:
    """Write a scenario as ``audio.flac``, ``array.json``, ``truth.json`` and ``tdoa_labels.csv``.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created if missing).
    scenario : ClickScenario
        The scenario.
    parameters : dict, optional
        Settings the scenario was drawn with, written into ``truth.json`` (see
        :func:`truth_document`).

    Returns
    -------
    list of pathlib.Path
        The written files.

    Notes
    -----
    FLAC holds at most 8 channels: a scenario with 9 or 10 sensors writes ``audio.wav``
    (24-bit PCM) instead of ``audio.flac``. ``tdoa_labels.csv`` (``time,i,j,tau,source``)
    holds the direct-path TDOA of every click and sensor pair, the labels
    ``fusion train-validator`` takes: ``time`` is the click's arrival at sensor ``i``, ``tau``
    its arrival at ``i`` minus at ``j``, s (true geometry and propagation). FLAC holds 24-bit
    integers in
    ``[-1, 1)``: the audio is scaled so its largest magnitude is :data:`FILE_PEAK` and the
    factor is stored as ``truth.json["audio_scale"]`` (file sample = ``audio_scale`` x scenario
    value). Every file is written atomically.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: output path exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    peak = float(np.max(np.abs(scenario.audio))) if scenario.audio.size else 0.0
    scale = FILE_PEAK / peak if peak > 0 else 1.0
    name = "audio.flac" if scenario.n_sensors <= FLAC_MAX_CHANNELS else "audio.wav"
    audio_path = write_audio(out / name, scenario.audio * np.float32(scale), scenario.fs)
    array_path = write_array(out / "array.json", scenario.sensors)
    truth_path = write_json(out / "truth.json", truth_document(scenario, audio_scale=scale,
                                                                     parameters=parameters))
    cols: dict[str, list[NDArray]] = {"time": [], "i": [], "j": [], "tau": [], "source": []}
    for src in scenario.sources:
        arr = src.arrival_times
        for i, j in scenario.pairs():
            n = arr.shape[0]
            for key, v in (("time", arr[:, i]), ("i", np.full(n, i)), ("j", np.full(n, j)),
                           ("tau", arr[:, i] - arr[:, j]), ("source", np.full(n, src.source_id))):
                cols[key].append(v)
    labels = {k: np.concatenate(v) if v else np.empty(0) for k, v in cols.items()}
    order = np.argsort(labels["time"], kind="stable")
    labels_path = write_table(out / "tdoa_labels.csv",
                              {k: (v[order].astype(int) if k in ("i", "j", "source") else v[order])
                               for k, v in labels.items()}, float_format="%.9f")
    logger.info("wrote click scenario (seed %d) to %s", scenario.seed, out)
    return [audio_path, array_path, truth_path, labels_path]
