"""Datasets on Dask: parallel = serial bytes, resume after deletion / corruption / kill, failures.

One ``LocalCluster`` of 2 worker processes serves the whole module; tiny
sequences (32x24 px, 30 ms) keep it fast.
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from evedge.io import read_hdf5
from evedge.parallel import ClusterError, dask_client
from evedge.sim.dataset import DatasetError, parse_dataset
from evedge.sim.dataset_run import (RUN_FIELDS, SequenceTask, generate_dataset, generate_sequence, read_manifest,
                                    sha256_file)

ROOT = Path(__file__).resolve().parents[2]

TINY = {
    "dataset": {"name": "tiny", "seed": 11, "count": 4},
    "parameters": {"family": {"choice": ["stripes", "shapes"]}, "sensor": "32x24", "duration_s": 0.03,
                   "frame_rate_hz": 100, "speed_px_s": {"log_uniform": [60, 240]},
                   "direction_deg": {"uniform": [0, 360]}, "shape_count": {"integers": [1, 2]},
                   "shape_radius_px": 5, "noise_rate_hz": {"choice": [0, 2]}, "threshold_mismatch": 0.02},
}


@pytest.fixture(scope="module")
def client():
    import cloudpickle

    # the fault-injecting tasks below live in this test module, which workers cannot import by name
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    with dask_client(workers=2) as c:
        yield c
    cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
    assert _workers_left() == [], "the cluster left worker processes behind"


def _workers_left(wait_s=10.0):
    """Child processes other than multiprocessing's resource tracker (which lives as long as we do)."""
    import psutil

    deadline = time.monotonic() + wait_s
    while True:
        left = []
        for p in psutil.Process().children(recursive=True):
            try:
                if "resource_tracker" not in " ".join(p.cmdline()):
                    left.append(p)
            except psutil.NoSuchProcess:  # exited while we looked
                pass
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.1)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The tiny dataset made serially in this process: the bytes every run must reproduce."""
    spec = parse_dataset(TINY, "tiny.toml")
    out = tmp_path_factory.mktemp("serial")
    rows = [generate_sequence(SequenceTask(spec, i, str(out), ("evedge",))) for i in range(spec.count)]
    assert all(r["status"] == "ok" for r in rows)
    return spec, out, rows


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted((folder / "sequences").glob("*.h5"))}


def _layout(path: Path) -> dict[str, tuple]:
    """Where each dataset's data lies in an HDF5 file: (offset or chunk offsets, stored bytes)."""
    out = {}

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset):
            if obj.chunks is None:
                out[name] = (obj.id.get_offset(), obj.id.get_storage_size())
            else:
                out[name] = (tuple(obj.id.get_chunk_info(k).byte_offset for k in range(obj.id.get_num_chunks())),
                             obj.id.get_storage_size())

    with h5py.File(path, "r") as f:
        f.visititems(visit)
    return out


def _assert_same_files(folder: Path, reference: Path, *, only_reference: bool = False) -> None:
    """The sequence files of ``folder`` are byte for byte the reference's; else say how they differ.

    The message tells a different recording (content) from the same recording laid out
    differently in the file (dataset offsets), naming the first differing byte.
    """
    from evedge._fuzz.targets import recording_digest

    got, want = _files(folder), _files(reference)
    if only_reference:
        got = {k: v for k, v in got.items() if k in want}
    assert sorted(got) == sorted(want), f"files {sorted(got)} vs the reference's {sorted(want)}"
    problems = []
    for name in sorted(want):
        a, b = got[name], want[name]
        if a == b:
            continue
        first = next((i for i, (x, y) in enumerate(zip(a, b)) if x != y), min(len(a), len(b)))
        same_content = recording_digest(read_hdf5(folder / name)) == recording_digest(read_hdf5(reference / name))
        moved = {k: (v, _layout(reference / name).get(k)) for k, v in _layout(folder / name).items()
                 if v != _layout(reference / name).get(k)}
        problems.append(f"{name}: {len(a)} vs {len(b)} bytes, first difference at byte {first}; recording "
                        f"{'the same (layout differs: ' + repr(moved)[:400] + ')' if same_content else 'DIFFERENT'}")
    assert not problems, "HDF5 bytes differ from the serial reference:\n" + "\n".join(problems)


def _stable(rows: dict) -> list[dict]:
    return [{k: v for k, v in rows[i].items() if k not in RUN_FIELDS} for i in sorted(rows)]


def test_two_workers_make_the_serial_bytes_and_resume_repairs(client, reference, tmp_path):
    spec, serial_dir, serial_rows = reference
    out = tmp_path / "ds"
    run = generate_dataset(spec, out, client=client, progress=False)
    assert (run.made, run.skipped, run.failed) == (4, 0, 0)
    _assert_same_files(out, serial_dir)
    rows = read_manifest(out)
    assert _stable(rows) == [{k: v for k, v in r.items() if k not in RUN_FIELDS} for r in serial_rows]
    # the two workers both took part (4 tasks, 2 single-threaded workers)
    assert len({r["worker"] for r in rows.values()}) == 2
    for r in rows.values():
        (rel, digest), = r["files"].items()
        assert sha256_file(out / rel) == digest
        rec = read_hdf5(out / rel)
        assert rec.events.shape[0] == r["n_events"] > 0
        assert rec.metadata["dataset"]["params"] == r["params"]
        assert rec.edges is not None and rec.truth is not None
    card = (out / "README.md").read_text()
    assert "| ok | 4 |" in card and f"| events | {sum(r['n_events'] for r in rows.values())} " in card
    assert "dask" in card

    # delete one file, flip a byte in another: the rerun redoes exactly those two
    victims = sorted((out / "sequences").glob("*.h5"))
    victims[0].unlink()
    data = bytearray(victims[2].read_bytes())
    data[len(data) // 2] ^= 0x01
    victims[2].write_bytes(bytes(data))
    run = generate_dataset(spec, out, client=client, progress=False)
    assert (run.made, run.skipped, run.failed) == (2, 2, 0)
    _assert_same_files(out, serial_dir)
    assert _stable(read_manifest(out)) == _stable(rows)
    # nothing left to do: no task at all
    run = generate_dataset(spec, out, client=client, progress=False)
    assert (run.made, run.skipped) == (0, 4)


def test_another_spec_into_the_same_folder_is_refused(client, reference, tmp_path):
    spec, _, _ = reference
    out = tmp_path / "ds"
    generate_dataset(parse_dataset(dict(TINY, dataset={"count": 1, "seed": 11, "name": "tiny"})), out,
                     client=client, progress=False)
    with pytest.raises(DatasetError, match="another spec"):
        generate_dataset(spec, out, client=client, progress=False)
    with pytest.raises(DatasetError, match="layouts"):
        generate_dataset(spec, tmp_path / "x", layouts=("zarr",), client=client, progress=False)
    with pytest.raises(DatasetError, match="does not exist"):
        generate_dataset(spec, tmp_path / "no" / "x", client=client, progress=False)


# --------------------------------------------------------------------------- failures
def _flaky(task):
    """Raises OSError on a sequence's first attempt (marker file), then works: Dask must retry it."""
    marker = Path(task.out_dir) / f".attempt-{task.index}"
    if task.index == 1 and not marker.exists():
        marker.touch()
        raise OSError("transient: disk hiccup")
    return generate_sequence(task)


def _killer(task):
    """Kills its worker process on sequence 2's first attempt: the nanny restarts it, the task is rescheduled."""
    marker = Path(task.out_dir) / f".killed-{task.index}"
    if task.index == 2 and not marker.exists():
        marker.touch()
        os._exit(1)
    return generate_sequence(task)


def _always_broken(task):
    if task.index == 3:
        raise RuntimeError("this sequence's task always breaks")
    return generate_sequence(task)


def test_a_worker_failure_retries_the_sequence(client, reference, tmp_path):
    spec, serial_dir, _ = reference
    out = tmp_path / "ds"
    run = generate_dataset(spec, out, client=client, progress=False, task_fn=_flaky)
    assert (run.made, run.failed) == (4, 0) and (out / ".attempt-1").exists()
    _assert_same_files(out, serial_dir)
    out2 = tmp_path / "ds2"
    run = generate_dataset(spec, out2, client=client, progress=False, task_fn=_killer)
    assert (run.made, run.failed) == (4, 0) and (out2 / ".killed-2").exists()
    _assert_same_files(out2, serial_dir)


def test_one_bad_sequence_is_reported_and_does_not_stop_the_others(client, reference, tmp_path):
    spec, serial_dir, _ = reference
    out = tmp_path / "ds"
    run = generate_dataset(spec, out, client=client, progress=False, retries=1, task_fn=_always_broken)
    assert (run.made, run.failed) == (3, 1)
    rows = read_manifest(out)
    assert rows[3]["status"] == "failed" and "always breaks" in rows[3]["error"] and rows[3]["files"] == {}
    assert all(rows[i]["status"] == "ok" for i in range(3))
    assert "## Failed sequences" in (out / "README.md").read_text()
    # a rerun with a working task makes only the failed one, and the dataset is whole
    run = generate_dataset(spec, out, client=client, progress=False)
    assert (run.made, run.skipped, run.failed) == (1, 3, 0)
    _assert_same_files(out, serial_dir)


def test_an_invalid_sequence_is_a_failed_row_naming_the_key(client, tmp_path):
    data = {"dataset": {"count": 6, "seed": 3},
            "parameters": {"sensor": "16x12", "duration_s": 0.01, "frame_rate_hz": 0, "contrast": 0.5,
                           "mean_intensity": {"choice": [0.5, 0.9]}}}
    spec = parse_dataset(data, "bright.toml")
    bright = {i for i in range(spec.count) if spec.sequence(i).params["mean_intensity"] == 0.9}
    assert 0 < len(bright) < spec.count
    run = generate_dataset(spec, tmp_path / "ds", client=client, progress=False)
    assert run.failed == len(bright)
    for i, row in run.rows.items():
        if i in bright:
            assert row["status"] == "failed"
            assert "bright.toml[" in row["error"] and "key 'stripes[0].light': must be <= 1" in row["error"]
        else:
            assert row["status"] == "ok"


# --------------------------------------------------------------------------- the command, killed midway
def _cli(spec: Path, out: Path, *extra, **kw):
    cmd = [sys.executable, "-m", "evedge.cli", "dataset", str(spec), "-o", str(out), "--quiet", *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True, **kw)


def _spec_file(path: Path, count: int) -> Path:
    """TINY with ``count`` sequences as a TOML file (sequence i does not depend on the count)."""
    data = json.loads(json.dumps(TINY))
    lines = ["[dataset]", 'name = "tiny"', "seed = 11", f"count = {count}", "[parameters]"]
    for k, v in data["parameters"].items():
        lines.append(f"{k} = " + (json.dumps(v) if not isinstance(v, dict) else
                                   "{ " + ", ".join(f"{a} = {json.dumps(b)}" for a, b in v.items()) + " }"))
    path.write_text("\n".join(lines) + "\n")
    return path


def _kill_after_first_sequence(spec_file: Path, out: Path) -> int:
    """Run the command, freeze it (SIGSTOP) as soon as a sequence file appears, kill it; files made."""
    proc = _cli(spec_file, out, "--workers", "1")
    try:
        deadline = time.monotonic() + 120
        while not list((out / "sequences").glob("seq_*.h5")) and time.monotonic() < deadline:
            if proc.poll() is not None:
                break  # finished (or failed) before a poll saw a file: the caller checks
            time.sleep(0.02)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGSTOP)  # the client and its cluster's processes, at once: no more writes
    finally:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        _, stderr = proc.communicate()
    assert proc.returncode in (0, -signal.SIGKILL), stderr.decode()
    return len(list((out / "sequences").glob("seq_*.h5")))


def test_command_killed_midway_then_rerun_gives_the_same_dataset(reference, tmp_path):
    spec, serial_dir, _ = reference
    # the first sequences are the reference's; a machine so loaded that the whole run ends before a poll
    # sees its first file gets a bigger dataset (at most twice): the kill must land midway
    for count in (10, 40, 160):
        out = tmp_path / f"ds{count}"
        spec_file = _spec_file(tmp_path / f"tiny{count}.toml", count)
        made_before = _kill_after_first_sequence(spec_file, out)
        if made_before < count:
            break
    assert 1 <= made_before < count, "the run was not killed midway"
    # as a kill in the middle of writes would leave them
    (out / "sequences" / ".seq_00003.h5.abcd.tmp").write_bytes(b"half")
    (out / ".manifest.jsonl.abcd.tmp").write_text("{")
    proc = _cli(spec_file, out, "--workers", "1")
    stdout, stderr = proc.communicate(timeout=600)
    assert proc.returncode == 0, stderr.decode()
    assert f"{count}/{count} sequences ok" in stdout.decode()
    assert len(_files(out)) == count
    _assert_same_files(out, serial_dir, only_reference=True)
    assert not list(out.glob("**/.*.tmp"))


def test_command_reports_a_bad_spec_without_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[dataset]\ncount = 2\n[parameters]\ncontrast = { uniform = [0.5, 3] }\n")
    proc = subprocess.run([sys.executable, "-m", "evedge.cli", "dataset", str(bad), "-o", str(tmp_path / "o")],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    assert "key 'parameters.contrast.uniform[1]': must be <= 1" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "o").exists()


def test_unreachable_scheduler_is_named():
    with pytest.raises(ClusterError, match="tcp://127.0.0.1:9"):
        with dask_client(scheduler="tcp://127.0.0.1:9", timeout_s=1):
            pass


# --------------------------------------------------------------------------- DSEC layout
def test_dsec_layout_reads_back_the_way_dsec_loaders_do(client, reference, tmp_path):
    spec, serial_dir, _ = reference
    out = tmp_path / "ds"
    generate_dataset(spec, out, client=client, progress=False)
    inodes = {p.name: p.stat().st_ino for p in (out / "sequences").glob("*.h5")}
    # adding a layout writes only the new files, from the verified evedge files (no new simulation)
    run = generate_dataset(spec, out, layouts=("evedge", "dsec"), client=client, progress=False)
    assert (run.made, run.skipped, run.failed) == (4, 0, 0)
    assert {p.name: p.stat().st_ino for p in (out / "sequences").glob("*.h5")} == inodes
    _assert_same_files(out, serial_dir)
    for i in range(spec.count):
        name = spec.sequence_name(i)
        ours = read_hdf5(out / "sequences" / f"{name}.h5").events
        with h5py.File(out / "dsec" / name / "events" / "left" / "events.h5", "r") as f:
            # as DSEC's EventSlicer: t = events/t + t_offset; ms_to_idx[k] = first event with t >= k ms
            t_offset = int(f["t_offset"][()])
            t = np.asarray(f["events/t"], dtype=np.int64) + t_offset
            x, y, p = (np.asarray(f[f"events/{k}"]) for k in "xyp")
            ms_to_idx = np.asarray(f["ms_to_idx"], dtype=np.int64)
            assert f["events/t"].dtype == np.uint32 and f["events/x"].dtype == np.uint16
            assert f["events/p"].dtype == np.uint8
        np.testing.assert_array_equal(t, ours["t"])
        np.testing.assert_array_equal(x, ours["x"])
        np.testing.assert_array_equal(y, ours["y"])
        np.testing.assert_array_equal(p, ours["p"].astype(np.uint8))
        rel = t - t_offset
        for k in range(ms_to_idx.size):  # slow reference of the definition
            first = next((j for j in range(rel.size) if rel[j] >= 1000 * k), rel.size)
            assert ms_to_idx[k] == first
        assert ms_to_idx[-1] == rel.size  # the last entry is past every event
    rows = read_manifest(out)
    assert all(len(r["files"]) == 2 for r in rows.values())
    # the same as a run that simulates both layouts at once
    both = tmp_path / "both"
    generate_dataset(spec, both, layouts=("evedge", "dsec"), client=client, progress=False)
    assert _stable(read_manifest(both)) == _stable(rows)
    # asking for one layout only keeps what is there
    run = generate_dataset(spec, out, layouts=("dsec",), client=client, progress=False)
    assert (run.made, run.skipped) == (0, 4)
    assert all(list(r["files"]) == [f"dsec/{r['name']}/events/left/events.h5"] for r in run.rows.values())


def test_a_cluster_needs_at_least_one_worker():
    with pytest.raises(ClusterError, match="workers must be an integer >= 1, got 0"):
        with dask_client(workers=0):
            pass


def test_run_tasks_bounds_the_tasks_in_flight(client):
    from evedge.parallel import run_tasks

    class Counting:
        """The client, counting the tasks submitted to it."""

        submitted = 0

        def submit(self, *args, **kw):
            Counting.submitted += 1
            return client.submit(*args, **kw)

    got, in_flight = [], []
    for item in run_tasks(Counting(), abs, [-k for k in range(25)], max_in_flight=3, progress=False):
        # submitted but not yet handed over, besides the one just handed over: 3 until the items run out
        in_flight.append(Counting.submitted - len(got) - 1)
        got.append(item)
    assert in_flight == [3] * 22 + [2, 1, 0]
    assert sorted(i for i, _, _ in got) == list(range(25))
    assert all(r == i and e is None for i, r, e in got)
    with pytest.raises(ValueError, match="max_in_flight must be an integer >= 1"):
        list(run_tasks(client, abs, [1], max_in_flight=0))


def test_a_link_in_the_dataset_folder_is_refused_and_nothing_behind_it_is_touched(client, reference, tmp_path):
    spec, _, _ = reference
    out = tmp_path / "ds"
    generate_dataset(parse_dataset(dict(TINY, dataset={"count": 1, "seed": 11, "name": "tiny"})), out,
                     client=client, progress=False)
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / ".seq_00000.h5.1.tmp").write_bytes(b"not yours")  # what a stale-temp sweep would delete
    for p in (out / "sequences").iterdir():
        p.unlink()
    (out / "sequences").rmdir()
    (out / "sequences").symlink_to(victim, target_is_directory=True)  # resuming would write through it
    with pytest.raises(DatasetError, match=r"sequences is a symbolic link: .* is not written into"):
        generate_dataset(spec, out, client=client, progress=False)
    assert sorted(os.listdir(victim)) == [".seq_00000.h5.1.tmp"]
