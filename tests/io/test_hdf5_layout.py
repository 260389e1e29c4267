"""The evedge HDF5 and DSEC writers give the same bytes however long Python keeps their dataset objects.

HDF5 writes a chunked dataset's chunks when its chunk cache is flushed; if
that waited for the dataset object to be freed, a reference cycle collected
later (as happens in long-lived worker processes) would move chunks in the
file. The writers flush each dataset at once; this holds every dataset
object alive until the file is closed and checks the bytes do not change.
"""

import h5py
import numpy as np
import pytest

from evedge.events import Frames, Recording, SensorSize, make_events
from evedge.io import write_recording
from evedge.io.dsec import write_dsec_events


def _recording():
    rng = np.random.default_rng(3)
    n = 3000
    ev = make_events(rng.integers(0, 32, n), rng.integers(0, 24, n), np.sort(rng.integers(0, 50_000, n)),
                     rng.integers(0, 2, n))
    truth = np.zeros(n, dtype=[("a", np.float64), ("b", np.float64), ("c", bool)])
    truth["a"] = 7.0  # constant columns compress to tiny chunks, which HDF5 places in shared blocks
    truth["b"] = rng.random(n)
    frames = Frames(np.arange(4, dtype=np.int64) * 10_000, rng.random((4, 24, 32)).astype(np.float32))
    edges = Frames(frames.t_us, rng.random((4, 24, 32)) < 0.1)
    return Recording(ev, SensorSize(32, 24), frames=frames, truth=truth, edges=edges, metadata={"k": 1})


@pytest.mark.parametrize("write", ["recording", "dsec"])
def test_same_bytes_when_dataset_objects_outlive_the_call(tmp_path, monkeypatch, write):
    rec = _recording()

    def run(path):
        if write == "recording":
            write_recording(path, rec)
        else:
            write_dsec_events(path, rec.events)
        return path.read_bytes()

    plain = run(tmp_path / "plain.h5")
    held = []
    create = h5py.Group.create_dataset

    def create_and_hold(self, *args, **kwargs):
        ds = create(self, *args, **kwargs)
        held.append(ds)  # as a reference cycle would, until the garbage collector runs
        return ds

    monkeypatch.setattr(h5py.Group, "create_dataset", create_and_hold)
    assert run(tmp_path / "held.h5") == plain
    assert held  # the patch was in the path


def test_holding_dataset_objects_does_move_chunks_without_a_flush(tmp_path):
    # the check above can fail: without the flush, held datasets give other bytes
    rec = _recording()
    held = []

    def write(path, hold):
        with h5py.File(path, "w", track_order=True) as f:
            g = f.create_group("truth", track_order=True)
            for name in rec.truth.dtype.names:
                ds = g.create_dataset(name, data=np.ascontiguousarray(rec.truth[name]), chunks=(1024,),
                                      compression="gzip", compression_opts=4, shuffle=True, track_times=False)
                if hold:
                    held.append(ds)
                del ds
        held.clear()
        return path.read_bytes()

    assert write(tmp_path / "a.h5", False) != write(tmp_path / "b.h5", True)
