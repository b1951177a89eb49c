"""Rebuild this trimmed copy of the XAV large-array recording (run from the repository root).

Reads ``../shared/realdata/xav_large_array`` (or ``$FUSION_REALDATA/xav_large_array``): the six
mono 24-bit WAVs, trimmed to the shortest, cut to two spans around kept localizations, written as
16-bit FLAC; the reference rows of the events inside each span with times made relative to the
span's start.
"""

from __future__ import annotations

import csv
import os
import shutil
from pathlib import Path

import soundfile as sf

HERE = Path(__file__).resolve().parent
SRC = Path(os.environ.get("FUSION_REALDATA", HERE.parents[3] / "shared" / "realdata")) / \
    "xav_large_array"
#: Spans (s in the original files): events 0, 1, 3 and events 21-29.
CUTS = {"cut1": (1.1, 2.6), "cut2": (11.2, 13.9)}


def main() -> None:
    """Write the FLACs, the reference CSVs, array.json and LICENSE.txt."""
    files = sorted((SRC / "data").glob("AMAR173.*.wav"))
    channels = [sf.read(f, dtype="float64")[0] for f in files]
    n = min(len(c) for c in channels)
    fs = sf.info(files[0]).samplerate
    rows = list(csv.DictReader((SRC / "reference_localizations_from_published_notebook.csv").open()))
    for name, (t0, t1) in CUTS.items():
        a, b = int(round(t0 * fs)), int(round(t1 * fs))
        for f, c in zip(files, channels, strict=True):
            sensor = f.name.split(".")[1]
            sf.write(HERE / f"{name}_AMAR173.{sensor}.flac", c[:n][a:b], fs, subtype="PCM_16")
        keep = [r for r in rows if t0 <= float(r["time_min_offset_s"]) and
                float(r["time_max_offset_s"]) <= t1]
        with (HERE / f"{name}_events.csv").open("w", newline="") as fh:
            out = csv.writer(fh)
            out.writerow(["detection_index", "t_start", "t_end", "f_low", "f_high",
                          "x_err_low_m", "x_err_high_m", "y_err_low_m", "y_err_high_m",
                          "z_err_low_m", "z_err_high_m", "kept_by_notebook_filter"])
            for r in keep:
                out.writerow([r["detection_index"],
                              f"{float(r['time_min_offset_s']) - t0:.4f}",
                              f"{float(r['time_max_offset_s']) - t0:.4f}",
                              r["frequency_min_hz"], r["frequency_max_hz"],
                              *(r[f"{a}_err_{s}_m"] for a in "xyz" for s in ("low", "high")),
                              r["kept_by_notebook_filter"]])
    for name in ("array.json", "LICENSE.txt"):
        shutil.copyfile(SRC / name, HERE / name)


if __name__ == "__main__":
    main()
