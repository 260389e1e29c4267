"""as_events / to_tonic / to_faery: other libraries' arrays in, evedge's out, losslessly."""

import numpy as np
import pytest

from evedge.events import (EVENT_DTYPE, FAERY_DTYPE, Recording, SensorSize, as_events, make_events, to_faery,
                           to_tonic, validate_events)

REF = make_events([0, 3, 7, 2], [1, 0, 5, 4], [10, 20, 20, 35], [1, 0, 1, 0])


def _like(dtype, events=REF, p_map=lambda p: p):
    out = np.empty(events.shape[0], dtype=dtype)
    names = out.dtype.names
    for key, aliases in {"x": ("x",), "y": ("y",), "t": ("t", "timestamp"), "p": ("p", "polarity", "on")}.items():
        name = next(a for a in aliases if a in names)
        out[name] = p_map(events["p"]) if key == "p" else events[key]
    return out


@pytest.mark.parametrize("dtype, p_map", [
    # faery / aedat
    ([("t", "<u8"), ("x", "<u2"), ("y", "<u2"), (("p", "on"), "?")], lambda p: p),
    # dv-processing EventStore.numpy()
    ([("timestamp", "<i8"), ("x", "<i2"), ("y", "<i2"), ("polarity", "i1")], lambda p: p.astype(np.int8)),
    # Prophesee Metavision EventCD
    ([("x", "<u2"), ("y", "<u2"), ("p", "<i2"), ("t", "<i8")], lambda p: p.astype(np.int16)),
    # other widths, big-endian, -1/+1 polarity, an extra field
    ([("x", ">i4"), ("y", "u1"), ("t", ">u8"), ("p", "i8"), ("extra", "f4")], lambda p: np.where(p, 1, -1)),
    ([("t", "m8[us]"), ("x", "i8"), ("y", "i8"), ("p", "u1")], lambda p: p.astype(np.uint8)),
])
def test_lossless_conversions_give_the_same_events(dtype, p_map):
    ev = as_events(_like(dtype, p_map=p_map))
    assert ev.dtype == EVENT_DTYPE
    assert ev.tobytes() == REF.tobytes()


def test_own_dtype_is_returned_as_is():
    assert as_events(REF) is REF
    assert validate_events(REF) is REF


def test_coarser_time_units_are_exact():
    a = np.zeros(2, dtype=[("x", "u2"), ("y", "u2"), ("t", "m8[ms]"), ("p", "?")])
    a["t"] = np.array([1, 2], dtype="m8[ms]")
    assert as_events(a)["t"].tolist() == [1000, 2000]
    b = a.astype([("x", "u2"), ("y", "u2"), ("t", "m8[ns]"), ("p", "?")])
    b["t"][1] += np.timedelta64(1, "ns")
    with pytest.raises(ValueError, match=r"field 't' \(timedelta64\[ns\]\) is not a whole number of microseconds at index 1"):
        as_events(b)


@pytest.mark.parametrize("dtype, fill, error, message", [
    ([("x", "f8"), ("y", "u2"), ("t", "i8"), ("p", "?")], {}, TypeError, "field 'x' must hold integer pixel coordinates"),
    ([("x", "i4"), ("y", "u2"), ("t", "i8"), ("p", "?")], {"x": [0, 40000]}, ValueError, "field 'x' at index 1 is 40000, outside int16"),
    ([("x", "u2"), ("y", "u2"), ("t", "f8"), ("p", "?")], {}, ValueError, "field 't' is float64.*seconds_to_us"),
    ([("x", "u2"), ("y", "u2"), ("t", "u8"), ("p", "?")], {"t": [0, 2**63]}, ValueError, "field 't' at index 1 .* beyond int64"),
    ([("x", "u2"), ("y", "u2"), ("t", "i8"), ("p", "i1")], {"p": [1, 2]}, ValueError, "field 'p' at index 1 is 2"),
    ([("x", "u2"), ("y", "u2"), ("t", "i8"), ("p", "i1")], {"p": [-1, 0]}, ValueError, "field 'p' mixes -1 and 0"),
    ([("x", "u2"), ("y", "u2"), ("t", "i8"), ("p", "f4")], {}, TypeError, "field 'p' must be bool or integer"),
    ([("x", "u2"), ("y", "u2"), ("t", "i8")], {}, TypeError, "no field for 'p'.*fields x, y, t"),
    ([("x", "u2"), ("y", "u2"), ("t", "i8"), ("timestamp", "i8"), ("p", "?")], {}, TypeError, "fields t, timestamp all could be 't'"),
])
def test_lossy_or_ambiguous_conversions_are_clear_errors(dtype, fill, error, message):
    a = np.zeros(2, dtype=dtype)
    for key, values in fill.items():
        a[key] = values
    with pytest.raises(error, match=message):
        as_events(a, name="mine")


def test_not_structured_and_not_1d():
    with pytest.raises(TypeError, match="mine: expected a structured array with fields x, y, t, p"):
        as_events(np.zeros(3), name="mine")
    with pytest.raises(TypeError, match="got list"):
        as_events([(1, 2, 3, True)])
    with pytest.raises(ValueError, match="expected a 1-D event array"):
        as_events(REF.reshape(2, 2))


def test_public_entry_points_take_converted_arrays():
    from evedge.detector.accumulate import accumulate_time
    from evedge.detector.pipeline import detect

    dv_like = _like([("timestamp", "<i8"), ("x", "<i2"), ("y", "<i2"), ("polarity", "i1")], p_map=lambda p: p.astype(np.int8))
    sensor = SensorSize(8, 6)
    a, b = detect(dv_like, sensor), detect(REF, sensor)
    assert a.lifetimes.tobytes() == b.lifetimes.tobytes() and (a.kept == b.kept).all()
    assert (accumulate_time(dv_like, sensor, [40], 100) == accumulate_time(REF, sensor, [40], 100)).all()
    rec = Recording(dv_like, sensor)
    assert rec.events.dtype == EVENT_DTYPE and rec.events.tobytes() == REF.tobytes()
    with pytest.raises(ValueError, match="field 't' is float64"):
        detect(dv_like.astype([("timestamp", "f8"), ("x", "<i2"), ("y", "<i2"), ("polarity", "i1")]), sensor)


def test_to_faery_and_to_tonic():
    f = to_faery(REF)
    assert f.dtype == FAERY_DTYPE and f["t"].tolist() == REF["t"].tolist() and f["on"].tolist() == REF["p"].tolist()
    assert as_events(f).tobytes() == REF.tobytes()
    assert to_tonic(REF) is REF
    with pytest.raises(ValueError, match="to_faery: events: field 't' at index 0 is -5; faery's t is unsigned"):
        to_faery(make_events([0], [0], [-5], [1]))


def test_with_real_faery():
    faery = pytest.importorskip("faery")
    assert faery.EVENTS_DTYPE == FAERY_DTYPE
    # faery's own stream output comes back as the same events
    out = faery.events_stream_from_array(to_faery(REF), dimensions=(8, 6)).to_array()
    assert as_events(out).tobytes() == REF.tobytes()


def test_with_real_tonic():
    tonic = pytest.importorskip("tonic")
    assert tonic.io.events_struct == EVENT_DTYPE
    made = tonic.io.make_structured_array(REF["x"], REF["y"], REF["t"], REF["p"])
    assert as_events(made).tobytes() == REF.tobytes()
    flipped = tonic.transforms.RandomFlipLR(sensor_size=SensorSize(8, 6).as_tonic(), p=1.0)(to_tonic(REF))
    assert (as_events(flipped)["x"] == 7 - REF["x"]).all()


def test_with_real_dv_processing():
    dv = pytest.importorskip("dv_processing")
    store = dv.EventStore()
    for e in REF:
        store.push_back(int(e["t"]), int(e["x"]), int(e["y"]), bool(e["p"]))
    assert as_events(store.numpy()).tobytes() == REF.tobytes()
