"""Readers and writers for the files the ``fusion`` command reads and writes.

Every reader validates what it reads and raises :class:`ValueError` (or :class:`FileNotFoundError`
for a missing file) whose message starts with the file's path and names the problem; the command
line turns these into one line on stderr and exit code 2. Readers never raise anything else for
bad file content (property-tested with random bytes and random CSV-like text).

Every writer is atomic (:func:`atomic_output`, from :mod:`fusion._output`): it writes a temporary
file beside the destination and renames it into place, so an interrupted or failed run never leaves
a half-written result; a symbolic link is written through; FIFOs and devices are refused; ``"-"``
(:data:`STDOUT`) writes to standard output.

Formats (``docs/formats.md``):

- sensor array ``array.json``: ``{"sound_speed": c, "sensors": [{"id", "x", "y", "z"}, ...]}``;
  sensors at distinct positions;
- audio, WAV or FLAC, channel ``i`` = ``sensors[i]`` (or one mono file per sensor, in array
  order; :func:`check_audio_files` is the one check of a recording's files);
- CSV tables with a header line; extra columns are ignored, missing required columns are errors;
- beam/frequency/time cubes ``.npz`` with ``power``, ``freqs``, ``scan_period``, ``aperture``,
  ``sound_speed``, all real numbers;
- JSON results.

Limits: CSV inputs at most :data:`MAX_CSV_BYTES` (1 GiB), lines at most :data:`MAX_LINE_CHARS`
characters, fields at most 128 KiB (the csv module's limit), numbers in commands' inputs at most
:data:`MAX_ABS_VALUE` (1e12) in magnitude; JSON at most :data:`MAX_JSON_BYTES`; whole-file audio
reads at most :data:`MAX_AUDIO_SAMPLES` samples.

Row order: readers of time series put each track's rows in time order (a stable sort by time when
some track is out of order, announced by one warning; rows already in order keep the file's
order) and refuse two rows of one track at the same time -- the algorithms are defined on
time-ordered samples with distinct times. Detections are put in ``event`` order the same way.

Chunked reading: :func:`iter_table` yields a CSV file's rows in chunks
(:class:`~fusion.io.tables.TableChunk`) with the checks of :func:`read_table`, and
:func:`write_table_chunks` writes chunks as they come, atomically; :func:`iter_amplitudes`,
:func:`iter_bearings` and :func:`iter_detections` (:mod:`~fusion.io.table_stream`) are the
chunked readers of those kinds, which raise :class:`RowOrderError` where the whole-file reader
would sort (callers then read the whole file).

Modules, one file kind each: :mod:`~fusion.io.tables` (CSV read and write),
:mod:`~fusion.io.table_kinds` (the named CSV kinds), :mod:`~fusion.io.table_stream`
(the chunked readers of time series), :mod:`~fusion.io.json_files`,
:mod:`~fusion.io.arrays` (``array.json``), :mod:`~fusion.io.audio` (WAV/FLAC),
:mod:`~fusion.io.cubes` (``.npz`` cubes), :mod:`~fusion.io.results` (localization results). The
data types the readers return, :class:`~fusion.types.Table` and :class:`~fusion.types.Cube`, live
in :mod:`fusion.types` so that algorithms need not import the I/O layer; every name is
re-exported here.
"""

from fusion._output import STDOUT, atomic_output
from fusion.io._files import (
    MAX_ABS_VALUE,
    MAX_AUDIO_SAMPLES,
    MAX_CSV_BYTES,
    MAX_JSON_BYTES,
    MAX_LINE_CHARS,
    PathLike,
)
from fusion.io.arrays import MIN_SENSOR_SEPARATION_M, read_array, write_array
from fusion.io.audio import (
    AudioFiles,
    check_audio_files,
    iter_audio_blocks,
    read_audio,
    read_audio_files,
    write_audio,
)
from fusion.io.cubes import read_cube, write_cube
from fusion.io.json_files import read_json, settings_path, write_json, write_settings
from fusion.io.results import (
    LocalizationResult,
    LocalizationWindow,
    SourceEstimate,
    TdoaRecord,
    read_localization,
    write_localization,
)
from fusion.io.table_kinds import (
    ALERT_KINDS,
    DETECTION_CLUES,
    TQI_STATES,
    TRACK_STATUSES,
    read_alerts,
    read_amplitudes,
    read_bearings,
    read_detections,
    read_ownship,
    read_smoothed,
    read_tma_bearings,
    read_tma_result,
    read_tqi,
    read_tracks,
)
from fusion.io.table_stream import (
    RowOrderError,
    TimeOrderCheck,
    iter_amplitudes,
    iter_bearings,
    iter_detections,
)
from fusion.io.tables import TableChunk, iter_table, read_table, write_table, write_table_chunks
from fusion.types import Cube, Table

__all__ = [
    "MAX_ABS_VALUE",
    "MAX_AUDIO_SAMPLES",
    "MAX_CSV_BYTES",
    "MAX_JSON_BYTES",
    "MAX_LINE_CHARS",
    "STDOUT",
    "Cube",
    "LocalizationResult",
    "LocalizationWindow",
    "SourceEstimate",
    "TdoaRecord",
    "read_localization",
    "write_localization",
    "Table",
    "atomic_output",
    "AudioFiles",
    "check_audio_files",
    "iter_audio_blocks",
    "iter_amplitudes",
    "iter_bearings",
    "iter_detections",
    "iter_table",
    "RowOrderError",
    "TableChunk",
    "TimeOrderCheck",
    "write_table_chunks",
    "read_amplitudes",
    "read_array",
    "read_audio",
    "read_audio_files",
    "read_bearings",
    "read_cube",
    "read_detections",
    "read_alerts",
    "read_json",
    "read_smoothed",
    "read_tma_result",
    "read_tqi",
    "read_tracks",
    "read_ownship",
    "read_table",
    "read_tma_bearings",
    "write_array",
    "write_audio",
    "write_cube",
    "settings_path",
    "write_json",
    "write_settings",
    "write_table",
    # also importable, as before the split into modules
    "ALERT_KINDS",
    "DETECTION_CLUES",
    "MIN_SENSOR_SEPARATION_M",
    "PathLike",
    "TQI_STATES",
    "TRACK_STATUSES",
]
