"""Read one mono audio file per sensor as one multichannel signal.

Recorders that write each hydrophone to its own file (e.g. ``AMAR173.1.wav`` .. ``AMAR173.6.wav``)
give files that start together but may end a few samples apart. :func:`read_audio_files` stacks
them in array order (file ``k`` = ``sensors[k]``), trims them to the shortest with one warning and
refuses files whose sample rates differ (no resampling: a rate mismatch means the files do not
belong together).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from fusion.io import read_audio

__all__ = ["read_audio_files"]

logger = logging.getLogger(__name__)


def _info(p: Path):
    import soundfile as sf

    if not p.is_file():
        raise FileNotFoundError(f"{p}: no such audio file")
    try:
        return sf.info(str(p))
    except (RuntimeError, sf.LibsndfileError) as e:  # LibsndfileError is a RuntimeError
        raise ValueError(f"{p}: not a readable WAV/FLAC audio file "
                         f"({' '.join(str(e).split())})") from None


def read_audio_files(
    paths: Sequence[str | os.PathLike[str]], n_channels: int
) -> tuple[NDArray[np.float64], float]:
    """Read one mono WAV/FLAC file per sensor into one (n_samples, n_channels) array.

    Parameters
    ----------
    paths : sequence of path-like
        One mono file per sensor, in array order.
    n_channels : int
        Number of sensors of the array; must equal the number of files.

    Returns
    -------
    samples : ndarray, shape (n_samples, n_channels)
        float64 samples in [-1, 1], column ``k`` from ``paths[k]``, trimmed to the shortest file.
    fs : float
        The common sample rate, Hz.

    Raises
    ------
    FileNotFoundError
        A file does not exist.
    ValueError
        A file count other than `n_channels`, a file that is not mono, not readable or empty,
        or sample rates that differ (the message lists every file with its rate).

    Notes
    -----
    Files of different lengths are trimmed at the end to the shortest, with one logged warning
    naming the lengths: files of one recorder start on the same sample.

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
    if isinstance(n_channels, bool) or int(n_channels) != n_channels or n_channels < 1:
        raise ValueError(f"n_channels must be a positive integer, got {n_channels!r}")
    files = [Path(p) for p in paths]
    if len(files) != n_channels:
        raise ValueError(f"{len(files)} audio file(s) for {n_channels} sensors (give one mono "
                         "file per sensor, in array order)")
    infos = [_info(p) for p in files]
    for p, info in zip(files, infos, strict=True):
        if info.channels != 1:
            raise ValueError(f"{p}: expected a mono file (one per sensor), got {info.channels} "
                             "channels")
    rates = [float(info.samplerate) for info in infos]
    if len(set(rates)) > 1:
        listing = ", ".join(f"{p} ({r:g} Hz)" for p, r in zip(files, rates, strict=True))
        raise ValueError(f"audio files have different sample rates: {listing}")
    columns = [read_audio(p, n_channels=1)[0][:, 0] for p in files]
    lengths = [c.shape[0] for c in columns]
    n = min(lengths)
    if len(set(lengths)) > 1:
        logger.warning("audio files differ in length (%s samples); trimmed to the shortest, %d "
                       "samples", ", ".join(str(k) for k in lengths), n)
    return np.stack([c[:n] for c in columns], axis=1), rates[0]
