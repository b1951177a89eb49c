"""Click localization at scale: chunks equal one pass, serial equals Dask, kill + rerun resumes."""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from hypothesis import given
from hypothesis import strategies as st
from threadpoolctl import threadpool_limits

from fusion.io import check_audio_files, read_array, write_json
from fusion.pipelines.clicks.chunks import (
    AudioSource,
    localize_chunk,
    plan_chunks,
    track_document_sources,
)
from fusion.pipelines.clicks.stream import stream_start
from fusion.pipelines.localization import ClickLocalization, result_document
from fusion.scale import (
    LocalPool,
    PartStore,
    dask_client,
    file_identity,
    fingerprint,
    run_tasks,
    task_runner,
)
from fusion.simulate.clicks import simulate_clicks, write_click_scenario

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    """One whale on four hydrophones, 20 s at 96 kHz, written as FLAC with its array."""
    out = tmp_path_factory.mktemp("rec")
    sc = simulate_clicks(seed=3, n_sensors=4, n_sources=1, duration_s=20.0, snr_db=30.0,
                         n_transients=2)
    write_click_scenario(out, sc)
    return out


def _args(rec: Path, out: Path, *extra: str, chunk: float = 4.0) -> list[str]:
    """5 windows of 12 s every 2 s; by default chunks of 2 windows (3 tasks, the last short)."""
    return ["localize", "--audio", str(rec / "audio.flac"), "--array", str(rec / "array.json"),
            "--out", str(out), "--chunk-s", str(chunk), "--quiet", *extra]


@pytest.fixture(scope="module")
def serial_bytes(recording, tmp_path_factory) -> bytes:
    """``fusion localize`` run serially (the default), the bytes of its result."""
    from fusion.cli import main

    out = tmp_path_factory.mktemp("serial") / "r.json"
    assert main(_args(recording, out)) == 0
    assert not Path(f"{out}.parts").exists()
    return out.read_bytes()


def test_stream_start_known_answers():
    """Starts sit on the block grid, two guards before a point where clicks become final."""
    assert stream_start(0, block=100, guard=10) == (0, 0)
    assert stream_start(150, block=100, guard=10) == (0, 0)  # only the recording's start fits
    assert stream_start(1000, block=100, guard=10) == (800, 890)
    assert stream_start(1000, block=100, guard=60) == (700, 840)
    assert stream_start(100, block=10, guard=95) == (0, 85)  # margin cut by the recording start
    assert stream_start(5, block=10, guard=200) == (0, 0)  # no finality point before it
    with pytest.raises(ValueError, match="block must be"):
        stream_start(10, block=0, guard=1)


@given(st.integers(0, 10**7), st.integers(1, 10**5), st.integers(0, 10**5))
def test_stream_start_invariants(window_start, block, guard):
    """start on the grid; final_from a finality point at or before the window, 2 guards in."""
    start, final_from = stream_start(window_start, block=block, guard=guard)
    assert start % block == 0 and 0 <= final_from <= window_start and start <= final_from
    if (start, final_from) != (0, 0):
        assert (final_from + guard) % block == 0
        assert final_from - 2 * guard >= start or start == 0


def test_measure_refuses_a_start_without_guards(recording):
    """A stream that starts less than two guards before final_from is refused."""
    pipe = ClickLocalization(localizer=None)
    src = AudioSource.of(check_audio_files([recording / "audio.flac"], 4))
    with pytest.raises(ValueError, match="two detector guards"):
        next(pipe.front_end.measure(src.blocks(block=192000, start=192000), fs=src.fs,
                                    sensors=read_array(recording / "array.json"),
                                    start_sample=192000, final_from=200000, first_window=2))


def test_workers_without_chunk_length_get_a_chunk_each(recording):
    """--workers N without --chunk-s: 60 s chunks unless the recordings give fewer than N; then
    the hop multiple that gives each worker one (5 windows, 2 workers: 3 and 2)."""
    from fusion.commands.localize import CHUNK_S, _default_chunk_s

    pipe = ClickLocalization(localizer=None)
    src = AudioSource.of(check_audio_files([recording / "audio.flac"], 4))
    assert _default_chunk_s([(src, None)], pipe, None) == CHUNK_S
    assert _default_chunk_s([(src, None)], pipe, 1) == CHUNK_S
    chunk = _default_chunk_s([(src, None)], pipe, 2)
    assert chunk == 6.0
    tasks = plan_chunks(src, pipe, chunk_s=chunk)
    assert [(t.first_window, t.stop_window) for t in tasks] == [(0, 3), (3, 5)]
    assert len(plan_chunks(src, pipe, chunk_s=_default_chunk_s([(src, None)], pipe, 8))) == 5
    assert _default_chunk_s([(src, None)] * 2, pipe, 2) == CHUNK_S  # a chunk per recording


def test_chunks_cover_each_window_once(recording):
    """The plan reports every window once, in order; each chunk measures its two neighbours."""
    pipe = ClickLocalization(localizer=None)
    src = AudioSource.of(check_audio_files([recording / "audio.flac"], 4))
    tasks = plan_chunks(src, pipe, chunk_s=4.0)
    assert [(t.first_window, t.stop_window) for t in tasks] == [(0, 2), (2, 4), (4, 5)]
    assert [(t.measure_first, t.measure_stop) for t in tasks] == [(0, 3), (1, 5), (3, 5)]
    assert all(t.start_sample % t.block == 0 for t in tasks)
    assert len({t.name for t in tasks}) == len(tasks)


def test_serial_run_equals_one_pass(recording, serial_bytes, tmp_path):
    """Chunked output is byte for byte write_json of one streaming pass (windows and tracks)."""
    sensors = read_array(recording / "array.json")
    info = sf.info(str(recording / "audio.flac"))
    fs, block = float(info.samplerate), int(round(2.0 * info.samplerate))

    def blocks():
        start = 0
        for x in sf.blocks(str(recording / "audio.flac"), blocksize=block, dtype="float32",
                           always_2d=True):
            yield start / fs, x
            start += x.shape[0]

    # the command's decisions from the first 60 s (here all) of the recording: replica, echoes,
    # sea floor, made by the pipeline itself as it streams; then, once every window is done,
    # the recording's sound speed
    from fusion.clicks.detect import ClickDetector
    from fusion.commands.localize import DETECT_FALSE_ALARMS_PER_S
    from fusion.pipelines.clicks import LLR_THRESHOLD, ClickFrontEnd, default_validator
    from fusion.pipelines.sound_speed import calibrate_speed

    # the windows' threshold from the noise false-alarm rate, as the command's (docs/localization.md
    # section 18); the decisions read the first minute at the fixed one
    detector = ClickDetector(false_alarms_per_s=DETECT_FALSE_ALARMS_PER_S)
    pipe = ClickLocalization(front_end=ClickFrontEnd(detector=detector,
                                                     validator=default_validator(LLR_THRESHOLD)))
    with threadpool_limits(1):  # as the chunk tasks (one BLAS thread, as on a Dask worker)
        windows = list(pipe.iter_windows(blocks(), fs=fs, sensors=sensors,
                                         duration_s=info.frames / fs))
    assert pipe.decisions is not None and pipe.decisions.replica is not None
    doc = result_document(windows)
    cal = calibrate_speed(doc["windows"], sensors.positions, sensors.sound_speed)
    doc["windows"] = [cal.apply(w) for w in doc["windows"]]
    doc["tracks"] = [t.to_dict() for t in track_document_sources(
        [(0.5 * (w["t_start"] + w["t_end"]), w["sources"]) for w in doc["windows"]])]
    ref = write_json(tmp_path / "one_pass.json", doc)
    assert ref.read_bytes() == serial_bytes
    doc = json.loads(serial_bytes)
    assert [w["t_start"] for w in doc["windows"]] == [0.0, 2.0, 4.0, 6.0, 8.0]
    assert sum(d["valid"] for w in doc["windows"] for d in w["tdoas"]) > 0


@pytest.fixture(scope="module")
def cluster():
    """A local Dask cluster of two worker processes (the one ``--workers 2`` starts)."""
    with dask_client(workers=2) as client:
        yield client


def test_dask_run_is_identical_to_serial(recording, serial_bytes, cluster, tmp_path):
    """On a 2-worker cluster (--scheduler ADDRESS), the result is byte-identical to serial."""
    from fusion.cli import main

    assert len(cluster.scheduler_info()["workers"]) == 2
    out = tmp_path / "r.json"
    assert main(_args(recording, out, "--scheduler", cluster.scheduler.address)) == 0
    assert out.read_bytes() == serial_bytes
    assert not Path(f"{out}.parts").exists()


def test_folder_of_recordings_on_dask(recording, serial_bytes, cluster, tmp_path):
    """A folder of recordings on the cluster: each output equals that file's serial run."""
    from fusion.cli import main

    folder = tmp_path / "archive"
    folder.mkdir()
    for name in ("a.flac", "b.FLAC"):
        (folder / name).symlink_to(recording / "audio.flac")
    (folder / "notes.txt").write_text("not audio", encoding="utf-8")
    out = tmp_path / "results"
    argv = ["localize", "--audio", str(folder), "--array", str(recording / "array.json"),
            "--out", str(out), "--chunk-s", "60", "--quiet", "--scheduler",
            cluster.scheduler.address]
    assert main(argv) == 0
    assert sorted(p.name for p in out.iterdir()) == ["a.json", "b.json",
                                                     "localize.settings.json"]
    assert (out / "a.json").read_bytes() == serial_bytes == (out / "b.json").read_bytes()


def test_workers_run_on_forked_processes_identical_to_serial(recording, serial_bytes, tmp_path,
                                                            monkeypatch):
    """``--workers 2`` runs the chunks on two processes forked from the command (no Dask
    cluster: it would cost seconds of CPU per worker); the result is byte-identical."""
    import distributed

    from fusion.cli import main

    def no_cluster(*args, **kwargs):
        raise AssertionError("--workers must not start a Dask cluster")

    monkeypatch.setattr(distributed, "LocalCluster", no_cluster)
    out = tmp_path / "r.json"
    assert main(_args(recording, out, "--workers", "2")) == 0
    assert out.read_bytes() == serial_bytes
    assert not Path(f"{out}.parts").exists()


def _part_of(shared, task):
    """A task of the forked-pool test: the worker's process id, the shared object, the task."""
    return json.dumps([os.getpid(), shared, task])


def test_local_pool_runs_each_task_once_in_other_processes(tmp_path):
    """Each task once, in a forked worker (another process id) that sees the shared object;
    a task whose part is stored is not run again."""
    store = PartStore(tmp_path / "parts", key="k")
    store.write("3", json.dumps([0, "old", 3]))
    with task_runner(workers=2) as pool:
        assert isinstance(pool, LocalPool) and pool.workers == 2
        run_tasks(_part_of, {"a": 1}, [0, 1, 2, 3], names=str, store=store, client=pool)
    got = {n: json.loads(store.read(n)) for n in sorted(store.names())}
    assert [got[n][1:] for n in "012"] == [[{"a": 1}, k] for k in range(3)]
    assert all(got[n][0] != os.getpid() for n in "012") and got["3"] == [0, "old", 3]
    with task_runner() as none:
        assert none is None
    with pytest.raises(ValueError, match="positive integer"):
        LocalPool(0)


def test_kill_then_rerun_resumes_byte_identical(recording, serial_bytes, tmp_path, caplog):
    """A killed run resumes from its own parts only; the result is byte-identical."""
    from fusion.cli import main

    out = tmp_path / "r.json"
    argv = _args(recording, out, chunk=2.0)  # 5 chunks of one window each
    parts = Path(f"{out}.parts")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "fusion", *argv], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120.0
    try:
        while not list(parts.glob("*/chunk-*.json")):
            assert proc.poll() is None and time.monotonic() < deadline, "no part before the end"
            time.sleep(0.02)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait()
    done = sorted(p.name for p in parts.glob("*/chunk-*.json"))
    assert 1 <= len(done) < 5 and not out.exists()
    # parts of another command (another key) beside them: removed, never read
    stale = parts / "0123456789abcdef"
    stale.mkdir()
    (stale / "chunk-000000.json").write_text("[]", encoding="utf-8")
    caplog.set_level(logging.INFO, logger="fusion.scale")
    assert main(argv) == 0
    assert f"{len(done)} of 5 parts already done" in caplog.text
    assert out.read_bytes() == serial_bytes
    assert not parts.exists()


def test_a_stored_part_is_used_as_written(tmp_path):
    """run_tasks computes only the tasks without a part and keeps the stored ones verbatim."""
    store = PartStore(tmp_path / "parts", key="k1")
    store.write("b", "stored")
    calls = []

    def square(shared, t):
        calls.append(t)
        return str(shared * t * t)

    finished = []
    run_tasks(square, 1, [2, 3, 4], names=lambda t: "abc"[t - 2],
              store=store, on_done=finished.append)
    assert calls == [2, 4] and sorted(finished) == [2, 3, 4]
    assert [store.read(n) for n in "abc"] == ["4", "stored", "16"]
    assert store.names() == {"a", "b", "c"}


def test_part_store_refuses_bad_names_and_removes_stale_keys(tmp_path):
    """Part names are plain file names; opening under a new key removes the other keys."""
    a = PartStore(tmp_path / "p", key="old")
    a.write("x", "1")
    with pytest.raises(ValueError, match="plain file name"):
        a.write("../x", "1")
    with pytest.raises(ValueError, match="key must be"):
        PartStore(tmp_path / "p", key="../up")
    b = PartStore(tmp_path / "p", key="new")
    assert b.names() == set() and not (tmp_path / "p" / "old").exists()
    b.write("y", "2")
    b.remove()
    assert not (tmp_path / "p").exists()


def test_fingerprint_follows_file_versions(tmp_path):
    """A rewritten audio file (other mtime or size) or another option changes the key."""
    f = tmp_path / "a.bin"
    f.write_bytes(b"123")
    k1 = fingerprint({"audio": [file_identity(f)], "hop": 2.0})
    assert k1 == fingerprint({"hop": 2.0, "audio": [file_identity(f)]})  # key order free
    assert k1 != fingerprint({"audio": [file_identity(f)], "hop": 1.0})
    st_ = f.stat()
    os.utime(f, ns=(st_.st_atime_ns, st_.st_mtime_ns + 10**9))
    assert k1 != fingerprint({"audio": [file_identity(f)], "hop": 2.0})
    assert file_identity(f, content=True)["sha256"].startswith("a665a459")


def test_dask_client_options():
    """Serial by default; a local cluster and a scheduler address together are refused."""
    with dask_client() as client:
        assert client is None
    with pytest.raises(ValueError, match="not both"), dask_client(workers=2, scheduler="tcp://x:1"):
        pass
    with pytest.raises(ValueError, match="positive integer"), dask_client(workers=0):
        pass


def test_audio_blocks_on_a_grid_from_any_start(recording):
    """Blocks from a start sample are the same samples as a read from the beginning."""
    src = AudioSource.of(check_audio_files([recording / "audio.flac"], 4))
    assert isinstance(src, AudioSource) and src.frames == 20 * 96000
    whole, _ = sf.read(str(recording / "audio.flac"), dtype="float32", always_2d=True)
    start = 7 * 1000
    got = list(src.blocks(block=96000, start=start))
    assert [t for t, _ in got][:2] == [start / src.fs, (start + 96000) / src.fs]
    np.testing.assert_array_equal(np.concatenate([x for _, x in got]), whole[start:])


@pytest.mark.parametrize("n_s, start, block", [(5, 0, 96000), (5, 7000, 50000), (20, 0, 96000),
                                               (5, 6 * 96000, 96000)])
def test_blocks_from_the_kept_start_are_the_decoded_samples(recording, monkeypatch, n_s, start,
                                                            block):
    """After start_samples, the next blocks copy the kept start and read on past it: the same
    blocks (grid, values) as a fresh read; the start is used once, then read from the file."""
    from fusion.pipelines.clicks import chunks

    src = AudioSource.of(check_audio_files([recording / "audio.flac"], 4))
    want = list(src.blocks(block=block, start=start))
    first = src.start_samples(n_s * 96000)
    np.testing.assert_array_equal(first, np.concatenate([x for _, x in want])[:n_s * 96000]
                                  if start == 0 else first)
    assert chunks._HELD and chunks._HELD[0][0] == src
    reads = []
    real = sf.blocks
    monkeypatch.setattr(sf, "blocks", lambda *a, **k: reads.append(k["start"]) or real(*a, **k))
    got = list(src.blocks(block=block, start=start))
    assert not chunks._HELD
    assert [t for t, _ in got] == [t for t, _ in want]
    for (_, x), (_, y) in zip(got, want, strict=True):
        assert x.dtype == y.dtype and x.flags.c_contiguous
        np.testing.assert_array_equal(x, y)
    if start + block <= n_s * 96000 < src.frames:  # the kept part was not decoded again
        assert reads and reads[0] >= block and reads[0] % block == start % block
    if n_s * 96000 >= src.frames:
        assert not reads


def _write(path, parts):
    """Write a DocumentText of `parts` to `path`; its summary."""
    from fusion.pipelines.clicks.chunks import DocumentText

    document = DocumentText(parts)
    path.write_text("".join(document), encoding="utf-8")
    return document.summary


def test_document_summary_counts_flagged_sources_apart(tmp_path):
    """DocumentText counts sources flagged unobservable, mirror-ambiguous or on <= 3 TDOAs."""
    import json

    def src(used, observable=True, mirror=False):
        return {"x": 0.0, "y": 0.0, "z": -900.0, "cov": np.eye(3).tolist(), "tdoas_used": used,
                "observable": observable, "mirror_ambiguous": mirror}

    w1 = {"t_start": 0.0, "t_end": 12.0, "tdoas": [{"valid": True}, {"valid": False}],
          "sources": [src(7), src(3), src(6, observable=False)]}
    w2 = {"t_start": 2.0, "t_end": 14.0, "tdoas": [{"valid": True}],
          "sources": [src(3, mirror=True), src(9)]}
    s = _write(tmp_path / "r.json", [json.dumps([w1]), json.dumps([w2])])
    assert (s.n_windows, s.n_valid_tdoas, s.n_sources) == (2, 2, 5)
    assert (s.n_unobservable, s.n_mirror, s.n_few_tdoas, s.n_flagged) == (1, 1, 2, 3)
    assert s.line() == ("2 windows, 2 valid TDOAs, 5 sources (3 flagged: 1 unobservable, "
                        "1 mirror-ambiguous, 2 on <= 3 TDOAs)")


def test_windows_not_localized_are_written_and_counted(tmp_path):
    """A window whose localizer failed carries the reason; the summary counts it."""
    import json

    w1 = {"t_start": 0.0, "t_end": 12.0, "tdoas": [{"valid": True}] * 3, "sources": [],
          "not_localized": "too few independent pairs"}
    w2 = {"t_start": 2.0, "t_end": 14.0, "tdoas": [], "sources": []}
    s = _write(tmp_path / "r.json", [json.dumps([w1, w2])])
    assert (s.n_not_localized, s.not_localized_reason) == (1, "too few independent pairs")
    assert s.line().endswith("; 1 windows not localized (e.g. too few independent pairs)")
    assert json.loads((tmp_path / "r.json").read_text())["windows"][0]["not_localized"] == \
        "too few independent pairs"


def _fails_or_sleeps(shared, task):
    """Task 0 fails at once; the others would run for a minute."""
    if task == 0:
        raise ValueError("task 0 failed")
    time.sleep(60)
    return "never"


def test_local_pool_stops_its_workers_when_a_task_fails(tmp_path):
    """A failed task is raised in the command at once; the workers still running are stopped
    rather than waited for, and nothing is stored for the unfinished tasks."""
    store = PartStore(tmp_path / "parts", key="k")
    t0 = time.monotonic()
    with pytest.raises(ValueError, match="task 0 failed"), task_runner(workers=2) as pool:
        run_tasks(_fails_or_sleeps, None, [0, 1, 2], names=str, store=store, client=pool)
    assert time.monotonic() - t0 < 30.0 and store.names() == set()


def test_chunk_reports_each_window_per_stage_without_changing_its_part(recording):
    """In this process a chunk reports every window it measures (its neighbours too) and every
    window it localizes; its part is the same text as without the report."""
    from fusion._progress import WindowProgress as _WindowProgress

    pipe = ClickLocalization()
    sensors = read_array(recording / "array.json")
    src = AudioSource.of(check_audio_files([recording / "audio.flac"], 4))
    tasks = plan_chunks(src, pipe, chunk_s=4.0)

    class Bar:
        def __init__(self):
            self.n, self.labels = 0, []

        def update(self, n=1):
            self.n += n

        def set_description(self, desc, refresh=True):
            self.labels.append(desc)

    bar = Bar()
    shown = _WindowProgress(bar, in_process=True)
    stages = []
    for t in tasks[:2]:
        before = bar.n
        quiet = localize_chunk((pipe, sensors), t)
        told = localize_chunk((pipe, sensors, lambda s: (stages.append(s), shown.window(s))), t)
        assert told == quiet
        assert bar.n - before == t.stop_window - t.first_window  # one step per own window
        shown.chunk_done(t)
        assert bar.n - before == t.stop_window - t.first_window  # nothing counted twice
    assert stages == (["measuring"] * 3 + ["localizing"] * 2) + (["measuring"] * 4 + ["localizing"] * 2)
    assert "localize: measuring" in bar.labels and bar.labels[-1] == "localize: localizing"
    shown.chunk_done(tasks[2])  # a chunk done elsewhere (a worker, an earlier run): whole
    assert bar.n == 5
