"""Audio files (WAV, FLAC): the checks of a recording's files, whole reads (one multichannel file
or one mono file per sensor), windowed reads of long recordings, atomic writes.

:func:`check_audio_files` is the one home of the checks every audio reader makes (the file exists
and is readable, channel and file counts match the array, one sample rate, samples present,
lengths trimmed to the shortest with one warning); the readers here and the chunked localization
of ``fusion localize`` (:class:`fusion.pipelines.clicks.chunks.AudioSource`) start from it.
"""

from __future__ import annotations

import errno
import logging
import math
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion._output import atomic_output
from fusion.io._files import MAX_AUDIO_SAMPLES, PathLike, _check_file

__all__ = ["AUDIO_SUFFIXES", "AudioFiles", "audio_files_of", "check_audio_files",
           "iter_audio_blocks", "read_audio", "read_audio_files", "write_audio"]

logger = logging.getLogger(__name__)


def _sf():
    import soundfile

    return soundfile


def _sf_message(e: Exception) -> str:
    return " ".join(str(e).replace("Error :", "").split()).rstrip(".")


def _audio_info(p: Path):
    sf = _sf()
    try:
        return sf.info(str(p))
    except (RuntimeError, sf.LibsndfileError) as e:  # LibsndfileError is a RuntimeError
        raise ValueError(f"{p}: not a readable WAV/FLAC audio file ({_sf_message(e)})") from None


@dataclass(frozen=True)
class AudioFiles:
    """A recording's audio files, checked by :func:`check_audio_files`.

    Attributes
    ----------
    paths : tuple of Path
        One multichannel file, or one mono file per sensor in array order.
    fs : float
        The common sample rate, Hz.
    frames : int
        Samples per channel: the shortest file's.
    channels : int
        Channels of the recording (of the one file, or the number of files).
    """

    paths: tuple[Path, ...]
    fs: float
    frames: int
    channels: int


def check_audio_files(
    paths: Sequence[str | os.PathLike[str]], n_channels: int | None = None
) -> AudioFiles:
    """Check a recording's audio files without reading their samples.

    Parameters
    ----------
    paths : sequence of path-like
        One multichannel file (channel ``k`` = sensor ``k``), or one mono file per sensor in
        array order.
    n_channels : int, optional
        Number of sensors of the array; without it one file may have any channel count and
        several files must be mono.

    Returns
    -------
    AudioFiles
        The paths, their common sample rate and the shortest file's length. Files of different
        lengths are trimmed to the shortest by the readers, announced here by one logged warning
        naming the lengths (files of one recorder start on the same sample).

    Raises
    ------
    FileNotFoundError
        A file does not exist.
    ValueError
        No file, a folder, a file that is not a readable WAV/FLAC file, a channel count other than
        `n_channels` (one file), a file count other than `n_channels` or a file that is not mono
        (several files), sample rates that differ (the message lists every file with its rate),
        a file without samples.

    Examples
    --------
    >>> import tempfile, soundfile
    >>> d = Path(tempfile.mkdtemp())
    >>> soundfile.write(d / "a.wav", np.zeros((100, 2)), 8000)
    >>> check_audio_files([d / "a.wav"], 2).frames
    100
    """
    if n_channels is not None and (isinstance(n_channels, bool) or int(n_channels) != n_channels
                                   or n_channels < 1):
        raise ValueError(f"n_channels must be a positive integer, got {n_channels!r}")
    files = [Path(p) for p in paths]
    if not files:
        raise ValueError("no audio file given")
    if len(files) > 1 and n_channels is not None and len(files) != n_channels:
        raise ValueError(f"{len(files)} audio files for {n_channels} sensors (give one "
                         "multichannel file, or one mono file per sensor in array order)")
    infos = [_audio_info(_check_file(p)) for p in files]
    if len(files) == 1:
        channels = infos[0].channels
        if n_channels is not None and channels != n_channels:
            raise ValueError(f"{files[0]}: audio has {channels} channel(s) but the array has "
                             f"{n_channels} sensors")
    else:
        channels = len(files)
        for p, info in zip(files, infos, strict=True):
            if info.channels != 1:
                raise ValueError(f"{p}: expected a mono file (one per sensor), got "
                                 f"{info.channels} channels")
    rates = [float(info.samplerate) for info in infos]
    if len(set(rates)) > 1:
        listing = ", ".join(f"{p} ({r:g} Hz)" for p, r in zip(files, rates, strict=True))
        raise ValueError(f"audio files have different sample rates: {listing}")
    lengths = [int(info.frames) for info in infos]
    for p, n in zip(files, lengths, strict=True):
        if n == 0:
            raise ValueError(f"{p}: audio file has no samples")
    if len(set(lengths)) > 1:
        logger.warning("audio files differ in length (%s samples); trimmed to the shortest, %d "
                       "samples", ", ".join(str(k) for k in lengths), min(lengths))
    return AudioFiles(tuple(files), rates[0], min(lengths), channels)


def read_audio_files(
    paths: Sequence[str | os.PathLike[str]], n_channels: int
) -> tuple[NDArray[np.float64], float]:
    """Read a recording -- one multichannel file, or one mono file per sensor -- into one array.

    Parameters
    ----------
    paths : sequence of path-like
        One file with `n_channels` channels, or `n_channels` mono files in array order.
    n_channels : int
        Number of sensors of the array.

    Returns
    -------
    samples : ndarray, shape (n_samples, n_channels)
        float64 samples in [-1, 1], column ``k`` from ``paths[k]`` (or channel ``k`` of the one
        file), trimmed to the shortest file.
    fs : float
        The common sample rate, Hz.

    Raises
    ------
    FileNotFoundError, ValueError
        As :func:`check_audio_files` and :func:`read_audio`.

    Examples
    --------
    >>> import tempfile, soundfile
    >>> d = Path(tempfile.mkdtemp())
    >>> for k, n in enumerate((100, 103)):
    ...     soundfile.write(d / f"h{k}.wav", np.zeros(n), 8000)
    >>> x, fs = read_audio_files([d / "h0.wav", d / "h1.wav"], 2)
    >>> x.shape, fs
    ((100, 2), 8000.0)
    """
    files = check_audio_files(paths, n_channels)
    if len(files.paths) == 1:
        return read_audio(files.paths[0], n_channels=n_channels)
    columns = [read_audio(p, n_channels=1)[0][:, 0] for p in files.paths]
    return np.stack([c[: files.frames] for c in columns], axis=1), files.fs


def read_audio(
    path: PathLike, *, n_channels: int | None = None
) -> tuple[NDArray[np.float64], float]:
    """Read a whole WAV/FLAC file.

    Parameters
    ----------
    path : path-like
        Audio file.
    n_channels : int, optional
        Expected channel count (e.g. the array's sensor count); a mismatch is an error.

    Returns
    -------
    samples : ndarray, shape (n_samples, n_channels)
        float64 samples in [-1, 1].
    fs : float
        Sample rate, Hz.

    Raises
    ------
    ValueError
        Unreadable, truncated or corrupt file (also when the damage is found while decoding),
        no samples, wrong channel count, more than :data:`MAX_AUDIO_SAMPLES` samples (read such
        a file with :func:`iter_audio_blocks`), NaN/inf samples.
    """
    checked = check_audio_files([path], n_channels)
    p = checked.paths[0]
    if checked.frames * checked.channels > MAX_AUDIO_SAMPLES:
        raise ValueError(f"{p}: {checked.frames} frames x {checked.channels} channels is more "
                         f"than {MAX_AUDIO_SAMPLES} samples; read it in blocks")
    sf = _sf()
    try:
        data, fs = sf.read(str(p), dtype="float64", always_2d=True)
    except (RuntimeError, sf.LibsndfileError) as e:
        raise ValueError(f"{p}: audio is truncated or corrupt ({_sf_message(e)})") from None
    if data.shape[0] == 0:
        raise ValueError(f"{p}: audio file has no samples")
    if not np.all(np.isfinite(data)):
        raise ValueError(f"{p}: audio contains NaN or infinite samples")
    return data, float(fs)


def iter_audio_blocks(
    path: PathLike, *, block_s: float, hop_s: float, n_channels: int | None = None
) -> Iterator[tuple[float, NDArray[np.float64], float]]:
    """Read a long recording in overlapping windows, never loading it whole.

    Parameters
    ----------
    path : path-like
        Audio file.
    block_s, hop_s : float
        Window length and hop, s.
    n_channels : int, optional
        Expected channel count.

    Yields
    ------
    t_start : float
        Start of the window, s from the start of the file.
    samples : ndarray, shape (n, n_channels)
        The window (the last one may be shorter).
    fs : float
        Sample rate, Hz.

    Raises
    ------
    ValueError
        As :func:`read_audio` (damage found while decoding a block included); a window or hop
        shorter than one sample, or a hop longer than the window (samples would be skipped).
    """
    if not (math.isfinite(block_s) and math.isfinite(hop_s)) or block_s <= 0 or hop_s <= 0:
        raise ValueError("window length and hop must be positive")
    checked = check_audio_files([path], n_channels)
    p, fs = checked.paths[0], checked.fs
    block, hop = int(round(block_s * fs)), int(round(hop_s * fs))
    if block < 1 or hop < 1:
        raise ValueError(f"window {block_s:g} s and hop {hop_s:g} s must each span at least one "
                         f"sample at {fs:g} Hz")
    if hop > block:
        raise ValueError(f"hop {hop_s:g} s is longer than the window {block_s:g} s; samples "
                         "would be skipped")
    sf = _sf()
    blocks = sf.blocks(str(p), blocksize=block, overlap=block - hop, dtype="float64",
                       always_2d=True)
    start = 0
    while True:
        try:
            data = next(blocks)
        except StopIteration:
            return
        except (RuntimeError, sf.LibsndfileError) as e:
            raise ValueError(f"{p}: audio is truncated or corrupt near {start * hop / fs:g} s "
                             f"({_sf_message(e)})") from None
        if not np.all(np.isfinite(data)):
            raise ValueError(f"{p}: audio contains NaN or infinite samples")
        yield start * hop / fs, data, fs
        start += 1


def write_audio(path: PathLike, samples: ArrayLike, fs: float, *, subtype: str | None = None) -> Path:
    """Write audio atomically; WAV or FLAC by the path's suffix.

    Parameters
    ----------
    path : path-like
        ``.wav`` or ``.flac`` destination.
    samples : array_like, shape (n_samples,) or (n_samples, n_channels)
        Samples in [-1, 1] (values outside are clipped by the encoder).
    fs : float
        Sample rate, Hz.
    subtype : str, optional
        soundfile subtype; defaults to 24-bit PCM.
    """
    p = Path(path)
    fmt = {".wav": "WAV", ".flac": "FLAC"}.get(p.suffix.lower())
    if fmt is None:
        raise ValueError(f"{p}: audio must be .wav or .flac")
    x = np.asarray(samples)
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{p}: refusing to write NaN or infinite samples")
    sf = _sf()
    with atomic_output(p) as tmp:
        try:
            sf.write(str(tmp), x, int(round(fs)), format=fmt, subtype=subtype or "PCM_24")
        except sf.LibsndfileError as e:  # a full disk is "System error." here: no errno
            raise OSError(errno.EIO, f"audio could not be written (libsndfile: {_sf_message(e)}; "
                          "is the disk full?)", str(p)) from None
    return p


#: Suffixes of the recordings a folder ``--audio`` holds.
AUDIO_SUFFIXES = (".wav", ".flac")


def audio_files_of(folder: Path) -> list[Path]:
    """The recordings (``.wav``, ``.flac``, any case) directly in `folder`, by name."""
    return sorted(p for p in Path(folder).iterdir()
                  if p.is_file() and p.suffix.lower() in AUDIO_SUFFIXES)
