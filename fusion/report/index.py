"""``summary.md`` of ``fusion report``: every figure of the folder linked with its one-line reading.

The same index ``fusion demo`` writes (:func:`fusion.report.figures.index_line`, one line per
figure: what it shows and its counts), with one section per result drawn into the folder: a
second ``fusion report`` into the same folder replaces its own result's section and keeps the
others, so the index always lists what the folder holds.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from fusion.report.figures import index_line

__all__ = ["SUMMARY_NAME", "summary_text", "write_summary"]

#: File name of the index in the output folder.
SUMMARY_NAME = "summary.md"
_HEAD = "# fusion report"
_INTRO = "Figures are linked relative to this file; one section per result drawn here."


def _sections(text: str) -> dict[str, list[str]]:
    """The ``## `` sections of an earlier report index (heading -> its lines)."""
    out: dict[str, list[str]] = {}
    current: str | None = None
    for line in text.splitlines():
        if line.startswith("## "):
            current = line
            out[current] = []
        elif current is not None and line.strip():
            out[current].append(line)
    return out


def summary_text(heading: str, readings: Mapping[str, str], *, earlier: str = "",
                 out_dir: Path | None = None) -> str:
    """The index after drawing one result.

    Parameters
    ----------
    heading : str
        The result's section title (its path and kind).
    readings : mapping of str to str
        File name -> one-line reading of each figure drawn, in order.
    earlier : str, keyword-only
        The folder's previous ``summary.md`` (a report index); its other results' sections are
        kept where their figures still exist in `out_dir`.
    out_dir : pathlib.Path, optional, keyword-only
        The folder (to check the kept sections' figures).

    Returns
    -------
    str

    Examples
    --------
    >>> print(summary_text("tma.csv (fusion tma)", {"tma.png": "plan view — observable: no"}))
    # fusion report
    <BLANKLINE>
    Figures are linked relative to this file; one section per result drawn here.
    <BLANKLINE>
    ## tma.csv (fusion tma)
    <BLANKLINE>
    - [tma.png](tma.png): plan view — observable: no
    <BLANKLINE>
    """
    keep: dict[str, list[str]] = {}
    if earlier.startswith(_HEAD):
        for head, lines in _sections(earlier).items():
            if head == f"## {heading}" or any(name in readings for name in _linked(lines)):
                continue
            if out_dir is not None and not all((out_dir / n).exists() for n in _linked(lines)):
                continue
            keep[head] = lines
    lines = [_HEAD, "", _INTRO, ""]
    for head, body in keep.items():
        lines += [head, "", *body, ""]
    lines += [f"## {heading}", ""]
    for name, reading in readings.items():
        what, _, numbers = reading.partition(" — ")
        lines.append(index_line(name, what or "figure", numbers))
    lines.append("")
    return "\n".join(lines)


def _linked(lines: list[str]) -> list[str]:
    """The files an index section links."""
    out = []
    for line in lines:
        if line.startswith("- [") and "](" in line:
            out.append(line.split("](", 1)[1].split(")", 1)[0])
    return out


def write_summary(out_dir: Path, heading: str, readings: Mapping[str, str]) -> Path:
    """Write ``out_dir/summary.md`` (atomic), keeping other results' sections; return its path."""
    from fusion.io import atomic_output

    path = Path(out_dir) / SUMMARY_NAME
    earlier = path.read_text(encoding="utf-8") if path.is_file() else ""
    text = summary_text(heading, readings, earlier=earlier, out_dir=Path(out_dir))
    with atomic_output(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return path
