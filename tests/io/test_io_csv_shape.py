"""Every CSV reader refuses a row with more fields than the header and a repeated column name.

All CSV readers of the project (:mod:`fusion.io.table_kinds`, :mod:`fusion.io.table_stream`, the
tables commands read with :func:`fusion.io.read_table`) share one reader
(:func:`fusion.io.tables.iter_table`); these tests run each of them.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from fusion import io

#: name -> (reader, a valid table's lines). The readers of commands (clicks of ``passive``,
#: events of ``localize``, labels of ``train-validator``) are ``read_table`` with their columns.
CSV_READERS: dict[str, tuple[Callable[[Path], object], list[str]]] = {
    "bearings": (io.read_bearings, ["track_id,time,bearing_deg", "0,0,10", "0,1,11", "1,0,50",
                                    "1,1,49"]),
    "amplitudes": (io.read_amplitudes, ["track_id,time,amplitude,residual", "0,0,1,0.1",
                                        "0,1,1,0.2"]),
    "detections": (io.read_detections, ["event,time,x,y,score", "0,0,1,2,0.5", "1,1,1,2,0.5"]),
    "ownship": (io.read_ownship, ["time,x,y", "0,0,0", "1,1,1"]),
    "tma_bearings": (io.read_tma_bearings, ["time,bearing_deg", "0,10", "1,11"]),
    "tqi": (io.read_tqi, ["track_id,time,amplitude,residual,tqi", "0,0,1,0.1,strong"]),
    "tracks": (io.read_tracks, ["track_id,event,time,x,y,vx,vy,status",
                                "0,0,0,1,1,0,0,confirmed"]),
    "alerts": (io.read_alerts, ["time,track_a,track_b,t_cross,kind", "0,0,1,5,predicted"]),
    "smoothed": (io.read_smoothed, ["track_id,time,bearing_deg,bearing_rate_deg_per_min,"
                                    "sigma_bearing_deg", "0,0,10,0.1,0.5", "0,1,11,0.1,0.5"]),
    "tma_result": (io.read_tma_result, ["time,x,y,vx,vy,sigma_x,sigma_y,range",
                                        "0,1,1,0,0,1,1,100"]),
    "iter_amplitudes": (lambda p: list(io.iter_amplitudes(p)),
                        ["track_id,time,amplitude,residual", "0,0,1,0.1", "0,1,1,0.2"]),
    "iter_bearings": (lambda p: list(io.iter_bearings(p)),
                      ["track_id,time,bearing_deg", "0,0,10", "0,1,11"]),
    "iter_detections": (lambda p: list(io.iter_detections(p)),
                        ["event,time,x,y", "0,0,1,2", "1,1,1,2"]),
    "passive_clicks": (lambda p: io.read_table(p, required=("beam", "freq"), optional=("time",),
                                               integer=("beam",)), ["beam,freq,time", "1,100,0"]),
    "localize_events": (lambda p: io.read_table(p, required=("t_start", "t_end"),
                                                optional=("f_low", "f_high")),
                        ["t_start,t_end", "0,1"]),
    "tdoa_labels": (lambda p: io.read_table(p, required=("time", "i", "j", "tau"),
                                            optional=("source",), integer=("i", "j", "source")),
                    ["time,i,j,tau,source", "0,0,1,0.001,0"]),
}


def _write(tmp_path: Path, lines: list[str]) -> Path:
    p = tmp_path / "t.csv"
    p.write_text("\n".join(lines) + "\n")
    return p


@pytest.mark.parametrize("kind", sorted(CSV_READERS))
def test_valid_table_is_read(kind, tmp_path):
    """Each reader takes a well-formed table (the shape checks refuse nothing valid)."""
    reader, lines = CSV_READERS[kind]
    assert reader(_write(tmp_path, lines)) is not None


@pytest.mark.parametrize("kind", sorted(CSV_READERS))
def test_row_with_more_fields_than_the_header_is_refused(kind, tmp_path):
    """``0,1,1,5,0.2`` under ``track_id,time,amplitude,residual``: which value is which?"""
    reader, lines = CSV_READERS[kind]
    n = len(lines[0].split(","))
    bad = [*lines, lines[-1] + ",7"]
    with pytest.raises(ValueError) as e:
        reader(_write(tmp_path, bad))
    msg = str(e.value)
    assert "t.csv" in msg and f"line {len(bad)}, column {n + 1}" in msg, msg
    assert f"{n + 1} fields" in msg and f"header names {n}" in msg, msg


@pytest.mark.parametrize("kind", sorted(CSV_READERS))
def test_repeated_column_name_is_refused(kind, tmp_path):
    reader, lines = CSV_READERS[kind]
    names = lines[0].split(",")
    header = [*names, names[1]]
    bad = [",".join(header)] + [row + ",0" for row in lines[1:]]
    with pytest.raises(ValueError) as e:
        reader(_write(tmp_path, bad))
    msg = str(e.value)
    assert f"t.csv: line 1, column {len(header)}: column name '{names[1]}' repeats column 2" in msg


def test_amplitudes_extra_field_from_the_report(tmp_path):
    """The reported case, through ``fusion tqi``: exit 2, one line, nothing written."""
    from fusion.cli import main

    src = _write(tmp_path, ["track_id,time,amplitude,residual", "0,0,1,0.1", "0,1,1,5,0.2"])
    assert main(["tqi", "--amplitudes", str(src), "--out", str(tmp_path / "o.csv")]) == 2
    assert not (tmp_path / "o.csv").exists()


def test_blank_header_names_may_repeat_and_short_rows_are_refused(tmp_path):
    """Trailing commas (empty names) are not names; a short row still names its line."""
    t = io.read_ownship(_write(tmp_path, ["time,x,y,,", "0,0,0,,", "1,1,1,,"]))
    assert t["x"].tolist() == [0.0, 1.0]
    with pytest.raises(ValueError, match=r"line 3 has 2 fields, header has 3"):
        io.read_ownship(_write(tmp_path, ["time,x,y", "0,0,0", "1,1"]))
