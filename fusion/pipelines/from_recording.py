"""Settings of the click localization decided from the recording itself (``docs/localization.md``).

Before the windows are processed, the first minute of a recording is examined once:

* the click replica is estimated from its strongest clicks (step 32 of the method,
  :meth:`fusion.clicks.detect.ClickDetector.with_recording_replica`), unless one is given;
* the detection band is the band of that estimate, the averaged click (step 32's "range of
  frequencies for the signal of interest", :func:`fusion.clicks.band.click_band`), unless one is
  given; without an estimate the detector's band stays;
* the bottom echoes are measured (:func:`fusion.clicks.echoes.bottom_echoes`): when the
  hydrophones hear their clicks followed by a floor echo, the detector drops echoes within the
  measured lags (:func:`fusion.clicks.echoes.echo_window`) and, when no sea floor is given and
  every sensor is below the surface z = 0, sources are searched above the deepest sensor minus
  :data:`fusion.clicks.echoes.FLOOR_MARGIN_M`;
* when no floor echo is heard, the hydrophones (all below the surface, no sea floor given) are
  taken as bottom-mounted, the method's range, and sources are searched above the same bound:
  a nearly flat array cannot tell a whale from its mirror image below it, and on a range that
  image is in the sea bed. ``--sea-floor-z-m`` gives another floor (hydrophones moored above it).

:func:`decide_from_recording` returns the detector and localizer settings to use, one line per
decision for the user and a JSON-ready record. Its one caller is
:meth:`fusion.pipelines.localization.ClickLocalization.with_recording_decisions`, which the
library's default chain (``ClickLocalization()`` run on a recording), ``fusion localize`` (which
prints the lines and writes the record beside its output) and the demo all go through.

Examples
--------
>>> from fusion.localization.whale_settings import LocalizerSettings
>>> from fusion.simulate.clicks import simulate_clicks
>>> sc = simulate_clicks(seed=21, n_sources=1, duration_s=20.0, echo="both")
>>> d = decide_from_recording(sc.audio, sc.fs, sc.sensors, settings=LocalizerSettings())
>>> d.replica is not None, d.echoes.near_floor, d.settings.sea_floor_z < -1600
(True, True, True)
>>> tuple(round(v) for v in d.detector.band_hz)  # 27-43 kHz widened to 26 kHz, below 45.6
(19600, 45600)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from fusion.clicks.band import BAND_DROP_DB, MIN_BAND_WIDTH_HZ, detection_band
from fusion.clicks.detect import ClickDetector
from fusion.clicks.echoes import FLOOR_MARGIN_M, BottomEchoes, bottom_echoes, echo_window
from fusion.clicks.replica import ReplicaEstimate
from fusion.geometry import SensorArray
from fusion.localization.surface_paths import SEA_SURFACE_Z
from fusion.localization.whale_settings import LocalizerSettings

__all__ = ["RECORDING_SPAN_S", "RecordingDecisions", "decide_from_recording", "recording_start"]

#: Seconds at the start of a recording examined for the decisions.
RECORDING_SPAN_S = 60.0


@dataclass(frozen=True)
class RecordingDecisions:
    """What :func:`decide_from_recording` decided.

    Attributes
    ----------
    detector : ClickDetector
        The detector to use (replica and echo window decided).
    settings : LocalizerSettings or None
        The localizer settings (sea floor decided), None when localization is off.
    replica : ReplicaEstimate or None
        The replica estimate when one was made.
    echoes : BottomEchoes
        The bottom-echo evidence.
    notes : tuple of str
        One line per decision, for the user.
    record : dict
        The decisions as JSON-ready values (``replica``, ``band`` and ``sea_floor``).
    """

    detector: ClickDetector
    settings: LocalizerSettings | None
    replica: ReplicaEstimate | None
    echoes: BottomEchoes
    notes: tuple[str, ...] = ()
    record: dict[str, Any] = field(default_factory=dict)


def decide_from_recording(
    samples: ArrayLike,
    fs: float,
    sensors: SensorArray,
    *,
    detector: ClickDetector | None = None,
    settings: LocalizerSettings | None = None,
    estimate_replica: bool = True,
    estimate_band: bool = True,
    replica_source: str = "generic",
    span: str = "the recording",
    weak_echoes: bool = True,
) -> RecordingDecisions:
    """Decide the replica, the detection band, the echo suppression and the sea floor from a
    recording's start.

    Parameters
    ----------
    samples : array_like, shape (n, n_sensors)
        The first :data:`RECORDING_SPAN_S` seconds (or all) of the recording.
    fs : float
        Sample rate, Hz.
    sensors : SensorArray
        The array.
    detector : ClickDetector, optional
        The detector to start from (default :class:`ClickDetector`).
    settings : LocalizerSettings, optional
        The localizer settings; a sea floor already set is kept. None: no localization.
    estimate_replica : bool, optional
        Estimate the replica (False: keep the detector's, named by `replica_source`).
    estimate_band : bool, optional
        Take the detection band from the estimated replica (False, or no estimate: keep the
        detector's band).
    replica_source : str, optional
        What the starting replica is, for the notes (e.g. a file name).
    span : str, optional
        How to name `samples` in the notes (e.g. "the first 60 s of a.flac").
    weak_echoes : bool, optional
        Once one channel shows a bottom echo, read the weaker echo evidence of the others
        (:attr:`fusion.clicks.echoes.BottomEchoes.heard`) for the majority and the echo window
        (False: every channel needs the full threshold, ``--strong-echoes-only``).

    Returns
    -------
    RecordingDecisions
    """
    given32 = np.asarray(samples)  # float32 from a file: the detector reads float32 itself
    x = np.asarray(samples, dtype=float)
    det = detector if detector is not None else ClickDetector()
    # the decisions read strong clicks at the fixed threshold; a threshold set from a noise
    # false-alarm rate (ClickDetector(false_alarms_per_s=...)) is the windows' and is kept
    rate = det.false_alarms_per_s
    det = det.with_false_alarms(None) if rate is not None else det
    est = None
    if estimate_replica:
        new, est = det.with_recording_replica(x, fs)
        if new is det:
            why = ("fewer than 20 clicks" if est is None else
                   f"the estimate did not settle (change {est.change:.3g} after "
                   f"{est.n_iterations} passes)")
            replica_note = f"replica: the {replica_source} one ({why} in {span})"
            replica_record: dict[str, Any] = {"source": replica_source, "reason": why}
            est = None
        else:
            det = new
            replica_note = (f"replica: estimated from {est.n_clicks} clicks of {span} "
                            f"({est.n_iterations} passes, last change {est.change:.2g}; "
                            "--replica generic to skip)")
            replica_record = {"source": f"estimated from {span}", "clicks": est.n_clicks,
                              "passes": est.n_iterations, "change": est.change,
                              "fs": est.replica.fs,
                              "samples": [float(v) for v in est.replica.samples]}
    else:
        replica_note, replica_record = f"replica: {replica_source}", {"source": replica_source}
    det, band_note, band_record = _band(det, est if estimate_band else None,
                                        given=not estimate_band, span=span)

    # the same clicks from float32 samples as from their float64 copy, without converting back
    clicks = det.detect(given32 if given32.dtype == np.float32 else x, fs)
    echoes = bottom_echoes(x, fs, clicks, band_hz=det.band_hz, weak=weak_echoes)
    given = settings is not None and settings.sea_floor_z is not None
    floor_record: dict[str, Any] = {
        "source": "given" if given else "none",
        "sea_floor_z": settings.sea_floor_z if given else None,
        "near_floor": echoes.near_floor,
        "bottom_echo_z": [None if not np.isfinite(v) else round(float(v), 2) for v in echoes.z],
        "bottom_echo_lag_s": [None if not np.isfinite(v) else float(v) for v in echoes.lag_s],
        "bottom_echo_heard": [bool(v) for v in echoes.heard], "weak_echoes": bool(weak_echoes)}
    notes = [replica_note, band_note]
    below = bool(np.all(sensors.positions[:, 2] < SEA_SURFACE_Z))
    if echoes.near_floor:
        window = echo_window(echoes)
        det = det.with_echo_window(window)
        floor_record["echo_window_s"] = list(window)
        note = (f"{echoes.describe()} in {span}: a click {window[0] * 1e3:.2g}-"
                f"{window[1] * 1e3:.2g} ms after a stronger one is taken as its echo")
        if settings is not None and not given and below:
            floor = float(sensors.positions[:, 2].min()) - FLOOR_MARGIN_M
            settings = dataclasses.replace(settings, sea_floor_z=floor)
            floor_record.update(source="bottom echoes", sea_floor_z=floor)
            note += f"; the sensors stand near the sea floor: sources searched above z = {floor:g} m"
        notes.append(note)
    elif settings is not None and not given and below:
        # no floor echo heard: the method's range (hydrophones on the sea floor) is assumed, so
        # that a whale and its mirror image through a nearly flat array are not both kept
        floor = float(sensors.positions[:, 2].min()) - FLOOR_MARGIN_M
        settings = dataclasses.replace(settings, sea_floor_z=floor)
        floor_record.update(source="bottom-mounted (no bottom echo heard)", sea_floor_z=floor)
        notes.append(f"no bottom echo heard in {span}: the hydrophones are taken as bottom-mounted "
                     f"(the method's range): sources searched above z = {floor:g} m "
                     "(--sea-floor-z-m for hydrophones moored above the floor)")
    if rate is not None:
        det = det.with_false_alarms(rate)
    return RecordingDecisions(det, settings, est, echoes, tuple(notes),
                              {"replica": replica_record, "band": band_record,
                               "sea_floor": floor_record})


def _band(det: ClickDetector, est: ReplicaEstimate | None, *, given: bool, span: str
          ) -> tuple[ClickDetector, str, dict[str, Any]]:
    """The detector with the band of the estimated replica (unchanged without an estimate or
    when the band is `given`), the note and the record."""
    lo, hi = det.band_hz
    if est is None:
        why = "given" if given else "no replica estimate"
        return (det, f"detection band: {lo / 1e3:.4g}-{hi / 1e3:.4g} kHz ({why})",
                {"source": why, "band_hz": [lo, hi]})
    lo, hi = detection_band(est.replica.samples, est.replica.fs)
    det = det.with_band((lo, hi))
    note = (f"detection band: {lo / 1e3:.4g}-{hi / 1e3:.4g} kHz, the -{BAND_DROP_DB:g} dB band of "
            f"the clicks averaged from {span}, at least {MIN_BAND_WIDTH_HZ / 1e3:g} kHz wide "
            "(--band-hz LOW HIGH to give one)")
    return det, note, {"source": "estimated replica", "band_hz": [lo, hi],
                       "drop_db": BAND_DROP_DB, "min_width_hz": MIN_BAND_WIDTH_HZ}


def recording_start(blocks: Iterable[tuple], fs: float, span_s: float = RECORDING_SPAN_S
                    ) -> tuple[np.ndarray, Iterator[tuple]]:
    """The first `span_s` seconds of a stream of audio blocks, and the whole stream again.

    Parameters
    ----------
    blocks : iterable of (t0, samples) or (t0, samples, fs)
        Consecutive blocks (n, n_sensors), as :meth:`fusion.pipelines.clicks.ClickFrontEnd.
        iter_windows` takes them.
    fs : float
        Sample rate, Hz.
    span_s : float, optional
        Seconds wanted (default :data:`RECORDING_SPAN_S`; all of a shorter stream).

    Returns
    -------
    samples : ndarray, shape (m, n_sensors)
        The first ``min(span_s fs, length)`` samples.
    blocks : iterator
        Every block of the stream from the first (those read to get `samples` are held).
    """
    want = int(round(span_s * fs))
    it = iter(blocks)
    held: list[tuple] = []
    n = 0
    while n < want:
        block = next(it, None)
        if block is None:
            break
        held.append(block)
        n += np.shape(block[1])[0]
    if not held:
        raise ValueError("no audio: the stream of blocks is empty")
    first = np.concatenate([np.asarray(b[1]) for b in held])[:want]

    def again() -> Iterator[tuple]:
        yield from held
        yield from it

    return first, again()
