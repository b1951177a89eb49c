"""Audio files (WAV, FLAC): whole reads, windowed reads of long recordings, atomic writes."""

from __future__ import annotations

import errno
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from fusion._output import atomic_output
from fusion.io._files import MAX_AUDIO_SAMPLES, PathLike, _check_file

__all__ = ["iter_audio_blocks", "read_audio", "write_audio"]


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
    p = _check_file(path)
    info = _audio_info(p)
    if n_channels is not None and info.channels != n_channels:
        raise ValueError(
            f"{p}: audio has {info.channels} channel(s) but the array has {n_channels} sensors"
        )
    if info.frames == 0:
        raise ValueError(f"{p}: audio file has no samples")
    if info.frames * info.channels > MAX_AUDIO_SAMPLES:
        raise ValueError(f"{p}: {info.frames} frames x {info.channels} channels is more than "
                         f"{MAX_AUDIO_SAMPLES} samples; read it in blocks")
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
    p = _check_file(path)
    info = _audio_info(p)
    if n_channels is not None and info.channels != n_channels:
        raise ValueError(
            f"{p}: audio has {info.channels} channel(s) but the array has {n_channels} sensors"
        )
    fs = float(info.samplerate)
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
