"""``summary.md`` of ``fusion demo``: every figure linked, with what it shows and its numbers.

Each part's section links every PNG file the part wrote (relative links, so the folder can be
moved or published as it is), one line per figure: what the figure shows and the part's measured
numbers that belong to it; the part's other numbers follow on one line. A figure this table does
not describe (a part that draws a new one) is still linked.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Protocol

from fusion.io import atomic_output
from fusion.report.figures import index_line

__all__ = ["FIGURES", "summary_lines", "write_summary"]

#: "part/figure.png" -> (what it shows, the summary numbers that go with it).
FIGURES: dict[str, tuple[str, tuple[str, ...]]] = {
    "acquisition/btr.png": (
        "integration-band bearing-time record with the true trace and the acquired line",
        ("true_bearing_deg", "bearing_deg", "true_rate_deg_per_min", "rate_deg_per_min",
         "snr_db", "default_used")),
    "clicks-scenario/clicks_correlogram.png": (
        "correlogram of the smoothed click maps of one sensor pair over time",
        ("candidate_tdoas", "valid_tdoas")),
    "clicks-scenario/clicks_tdoas.png": (
        "TDOAs per window (valid and rejected) over the true delays",
        ("valid_tdoas", "valid_true_fraction", "tdoa_abs_error_median_us", "tdoa_crb_median_us")),
    "clicks-scenario/clicks_surfaces.png": (
        "intensity surfaces of one window with the localized and the true sources",
        ("surface_window_s", "sources", "sources_flagged", "whales_found", "false_fixes",
         "source_error_median_m")),
    "clicks-scenario/clicks_sources.png": (
        "localized sources against the true positions",
        ("sources", "sources_flagged", "whales_found", "false_fixes", "source_error_median_m")),
    "clicks-scenario/clicks_tracks.png": (
        "whale tracks in plan view and depth (replica, echoes and sea floor from the recording)",
        ("tracks", "sources", "sources_flagged", "whales_found", "false_fixes",
         "source_error_median_m", "replica_estimated",
         "bottom_echoes", "sea_floor_z")),
    "tma/tma.png": (
        "plan view: own-ship, true target and the TMA estimate with 2-sigma ellipses",
        ("final_range_error_pct", "final_position_error_m", "nees_4dof", "observable")),
    "tqi/tqi_timeline.png": (
        "amplitude, residual, SLLRs and TQI state of one track, with and without hysteresis",
        ("changes_hysteresis", "changes_single_threshold", "loss_onset_update",
         "lost_declared_hysteresis", "lost_declared_single_threshold")),
    "tqi/cube_track.png": (
        "BTR of a simulated cube with the tracker's bearings, and its bearing error",
        ("cube_acq_rate_deg_per_min", "cube_true_rate_deg_per_min", "cube_rms_bearing_error_deg",
         "cube_never_lost")),
    "crossings/crossings.png": (
        "bearing-time tracks with the predicted and detected crossing alerts",
        ("true_crossings", "predicted_ahead", "detected", "median_detection_delay_s",
         "false_alert_pairs")),
    "active/plan_view.png": (
        "multistatic tracks in plan view, fuzzy association against the Kalman tracker",
        ("fuzzy_coverage", "fuzzy_false_tracks", "kalman_coverage", "kalman_false_tracks")),
    "smoothing/smoothing.png": (
        "unlabeled detections, smoothed tracks with 1-sigma bands, true crossings and alerts",
        ("tracks", "true_tracks", "swaps", "lost", "median_track_rmse_deg", "raw_noise_deg")),
    "passive/passive.png": (
        "bearing-time tracks coloured by TQI over the truth, with crossing alerts and episodes",
        ("tracks", "kept", "swaps", "rmse_deg", "alerts")),
}


class PartLike(Protocol):
    """What the summary needs of a part's result (:class:`fusion.demo.PartResult`)."""

    name: str
    ok: bool
    seconds: float
    summary: dict[str, Any]


def _numbers(summary: Mapping[str, Any], keys: Sequence[str]) -> str:
    return ", ".join(f"{k}={summary[k]}" for k in keys if k in summary)


def summary_lines(out_dir: Path, *, seed: int, results: Sequence[PartLike]) -> list[str]:
    """The lines of ``summary.md`` (Markdown) for the parts' results in `out_dir`.

    Parameters
    ----------
    out_dir : pathlib.Path
        The demo's output folder; each part's figures are its ``name/*.png`` files.
    seed : int, keyword-only
        Scenario seed.
    results : sequence of PartResult, keyword-only
        The parts run, in order.

    Returns
    -------
    list of str
    """
    lines = ["# fusion demo", "", f"seed {seed}; figures are linked relative to this file.", ""]
    for r in results:
        lines += [f"## {r.name} — {'ok' if r.ok else 'FAILED'} ({r.seconds:.1f} s)", ""]
        shown: set[str] = set()
        for png in sorted((Path(out_dir) / r.name).glob("*.png")):
            rel = f"{r.name}/{png.name}"
            what, keys = FIGURES.get(rel, (f"figure of the {r.name} part", ()))
            nums = _numbers(r.summary, keys)
            shown.update(k for k in keys if k in r.summary)
            lines.append(index_line(rel, what, nums))
        rest = [k for k in r.summary if k not in shown]
        if rest:
            lines.append(f"- numbers: {_numbers(r.summary, rest)}")
        lines.append("")
    return lines


def write_summary(out_dir: Path, *, seed: int, results: Sequence[PartLike]) -> Path:
    """Write ``out_dir/summary.md`` (atomic); return its path. See :func:`summary_lines`."""
    path = Path(out_dir) / "summary.md"
    with atomic_output(path) as tmp:
        tmp.write_text("\n".join(summary_lines(out_dir, seed=seed, results=results)),
                       encoding="utf-8")
    return path
