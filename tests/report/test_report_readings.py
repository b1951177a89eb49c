"""What the figures and the report's index tell a reader: counts, flags, channels, visible sizes.

Each test asserts on the figure objects (artists, labels, titles) or on the index text, not on
pixels: summary.md merges results drawn into one folder, uncertainty thinner than a few pixels is
widened with a note, track identity is colour and TQI state is marker shape, a TMA range flagged
unobservable says so, a localization summary counts fixed and flagged sources, and depth is
depth only where everything is under the surface.
"""

from __future__ import annotations

import contextlib
import io

import numpy as np
import pytest

from fusion.cli import main
from fusion.geometry import SensorArray
from fusion.report.figures import (
    MIN_UNCERTAINTY_PX,
    TQI_MARKERS,
    covariance_ellipse,
    ensure_visible,
    new_figure,
    sigma_band,
)
from fusion.report.index import summary_text
from fusion.report.localization import Fixes, fix_counts, fixes_figure
from fusion.types import Table


def _cli(*argv: object) -> int:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main([str(a) for a in argv])


# ---- summary.md of fusion report -------------------------------------------------------------

def test_report_index_lists_each_result_once_and_keeps_the_others(tmp_path):
    """Two results drawn into one folder: both sections; drawing the first again replaces its
    section (no duplicate), and a section whose figures are gone is dropped."""
    from fusion.simulate import tma

    tma.write_scenario(tmp_path / "sc", seed=3)
    assert _cli("tma", "--bearings", tmp_path / "sc" / "bearings.csv", "--ownship",
                tmp_path / "sc" / "ownship.csv", "--out", tmp_path / "tma.csv") == 0
    out = tmp_path / "figs"
    assert _cli("report", tmp_path / "tma.csv", "--out", out) == 0
    index = (out / "summary.md").read_text(encoding="utf-8")
    assert index.startswith("# fusion report")
    line = next(ln for ln in index.splitlines() if ln.startswith("- [tma.png](tma.png): "))
    assert "final range" in line and "range observable" in line

    earlier = "\n".join([*index.splitlines(), "", "## other.json (fusion localize)", "",
                         "- [localize.png](localize.png): sources — 3 sources", ""])
    (out / "localize.png").write_bytes(b"png")
    again = summary_text(f"{tmp_path / 'tma.csv'} (fusion tma)", {"tma.png": "plan — n"},
                         earlier=earlier, out_dir=out)
    assert again.count("## ") == 2 and again.count("[tma.png]") == 1
    assert "[localize.png](localize.png)" in again
    (out / "localize.png").unlink()
    gone = summary_text("x (fusion tma)", {"tma.png": "plan — n"}, earlier=earlier, out_dir=out)
    assert "localize.png" not in gone


def test_demo_and_report_share_the_index_line():
    """The demo's summary and the report's index write a figure's line the same way."""
    from fusion.demos.summary import summary_lines
    from fusion.report.figures import index_line

    assert index_line("a/b.png", "what", "n=1") == "- [b.png](a/b.png): what — n=1"
    text = summary_text("r (k)", {"b.png": "what — n=1"})
    assert "- [b.png](b.png): what — n=1" in text
    assert callable(summary_lines)


# ---- visible uncertainty ---------------------------------------------------------------------

def test_thin_bands_and_small_ellipses_are_widened_with_a_note():
    """A 1-sigma band and a 2-sigma ellipse far below a pixel are drawn MIN_UNCERTAINTY_PX wide
    (the figure says so); wide ones are left as they are."""
    from matplotlib.patches import Ellipse

    fig, (ax, ax2) = new_figure(1, 2)
    t = np.linspace(0.0, 1000.0, 50)
    sigma_band(ax, t, np.linspace(0, 5000.0, 50), np.full(50, 1e-3))    # 1 mm on 5 km
    covariance_ellipse(ax2, (0.0, 0.0), np.eye(2) * 1e-6)                  # 2 mm on 1 km
    ax2.plot([-500, 500], [-500, 500])
    ax2.set_aspect("equal")
    assert ensure_visible(fig) == 2
    for a in (ax, ax2):
        assert any(txt.get_gid() == "uncertainty-note" for txt in a.texts)
    ell = next(p for p in ax2.patches if isinstance(p, Ellipse))
    px_per_m = abs(np.diff(ax2.transData.transform([[0, 0], [1, 0]])[:, 0])[0]) * 100 / fig.dpi
    assert ell.get_width() * px_per_m >= MIN_UNCERTAINTY_PX * 0.99
    band = next(c for c in ax.collections if getattr(c, "_uncertainty", None) is not None)
    _, _, half, *_ = band._uncertainty
    py_per_unit = abs(np.diff(ax.transData.transform([[0, 0], [0, 1]])[:, 1])[0]) * 100 / fig.dpi
    assert 2 * half.min() * py_per_unit >= MIN_UNCERTAINTY_PX * 0.99

    fig2, ax3 = new_figure()
    sigma_band(ax3, t, np.linspace(0, 10.0, 50), np.full(50, 2.0))
    assert ensure_visible(fig2) == 0 and not ax3.texts


# ---- identity in colour, state in marker -----------------------------------------------------

def test_tqi_states_are_markers_in_the_track_colour():
    """On the passive tracks figure each track keeps one colour, and the states are marker
    shapes of that colour; no state has a colour of its own."""
    from matplotlib.colors import to_rgba

    from fusion.report.bearing_time import smoothed_figure

    n = 40
    rows = {"track_id": np.repeat([1, 2], n), "time": np.tile(np.arange(n) * 10.0, 2),
            "bearing_deg": np.r_[np.linspace(30, 60, n), np.linspace(90, 70, n)],
            "bearing_rate_deg_per_min": np.ones(2 * n), "sigma_bearing_deg": np.full(2 * n, 0.5)}
    tqi = np.array(["strong", "low_snr", "uncertain", "lost"] * (2 * n // 4))
    fig = smoothed_figure(Table(rows), tqi=tqi, title="t")
    ax = fig.axes[0]
    marks = [ln for ln in ax.lines if str(ln.get_gid()).startswith("tqi-")]
    assert {ln.get_gid()[4:] for ln in marks} == set(TQI_MARKERS)
    assert {ln.get_marker() for ln in marks} == set(TQI_MARKERS.values())
    colours = {to_rgba(ln.get_color()) for ln in marks}
    assert len(colours) == 2  # one per track, whatever the state
    track_lines = {to_rgba(ln.get_color()) for ln in ax.lines if ln.get_label().startswith("track")}
    assert colours == track_lines


# ---- TMA flag --------------------------------------------------------------------------------

def _tma_table(observable: int) -> Table:
    t = np.arange(10.0)
    return Table({"time": t, "x": 1000 + t, "y": 2000 + t, "vx": np.ones(10), "vy": np.ones(10),
                  "sigma_x": np.full(10, 50.0), "sigma_y": np.full(10, 50.0),
                  "range": np.full(10, 2236.0), "range_low": np.full(10, 300.0),
                  "range_high": np.full(10, 1e12), "observable": np.full(10, observable)})


@pytest.mark.parametrize("observable", [0, 1])
def test_tma_figure_says_when_range_is_unobservable(observable):
    from fusion.report.positions import tma_figure

    fig = tma_figure(_tma_table(observable), title="t")
    title = fig.get_suptitle()
    notes = [txt.get_text() for a in fig.axes for txt in a.texts]
    if observable:
        assert "UNOBSERVABLE" not in title and "(range observable)" in title
        assert not any("UNOBSERVABLE" in n for n in notes)
    else:
        assert title.startswith("RANGE UNOBSERVABLE")
        assert sum("UNOBSERVABLE" in n for n in notes) == 2  # plan view and range panel


# ---- localization counts and depth -----------------------------------------------------------

def _fixes(z: float, good: list[bool]) -> Fixes:
    n = len(good)
    xyz = np.c_[np.arange(n, dtype=float), np.zeros(n), np.full(n, z)]
    return Fixes(np.arange(n, dtype=float), xyz, np.tile(np.eye(3) * 0.01, (n, 1, 1)),
                 np.array(good), (), [])


def test_localization_reading_counts_fixed_and_flagged():
    """The figure's line counts flagged fixes apart: no error is quoted without the counts."""
    f = _fixes(-900.0, [True, False, True])
    assert fix_counts(f, "localization").startswith("3 sources, 2 fixed, 1 flagged")
    fig = fixes_figure(f, title="t")
    assert "2 sources (1 not fixed)" in fig.get_suptitle()


@pytest.mark.parametrize(("z", "sensor_z", "label", "inverted"), [
    (-900.0, -1500.0, "depth, m", True),                            # a range: depth down
    (-1.0, 0.5, "height z, m (z up, array frame)", False),          # a frame around z = 0
])
def test_depth_axis_only_under_the_surface(z, sensor_z, label, inverted):
    """No negative depths: an array around z = 0 is drawn in its own frame, height up."""
    array = SensorArray(np.array([[0, 0, sensor_z], [1, 0, -1.0], [0, 1, -1.2]], dtype=float),
                        sound_speed=1500.0)
    fig = fixes_figure(_fixes(z, [True, True]), array=array, title="t")
    ax_d = next(a for a in fig.axes if a.get_xlabel() == "time, s")
    assert ax_d.get_ylabel() == label
    assert bool(ax_d.yaxis_inverted()) is inverted
    if inverted:
        ys = np.concatenate([ln.get_ydata() for ln in ax_d.lines if len(ln.get_ydata())])
        assert np.all(np.asarray(ys, dtype=float) >= 0)
