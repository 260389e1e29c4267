"""The validated-once marker (:func:`evedge.detector._checks.validated`): O(1) checks, and honest."""

import threading

import numpy as np
import pytest

from evedge.detector import Detector, detect, edge_frames
from evedge.detector import _checks
from evedge.detector._checks import check_events, validated
from evedge.events import SensorSize, make_events

SIZE = SensorSize(16, 12)


def _events(n=400, seed=0):
    g = np.random.default_rng(seed)
    return make_events(g.integers(0, SIZE.width, n), g.integers(0, SIZE.height, n), np.sort(g.integers(0, 50_000, n)),
                       g.random(n) < 0.5)


@pytest.fixture
def count(monkeypatch):
    """Number of O(n) validations (calls of validate_events behind check_events)."""
    calls = []
    real = _checks.validate_events

    def counting(events, *args, **kw):
        calls.append(len(events))
        return real(events, *args, **kw)

    monkeypatch.setattr(_checks, "validate_events", counting)
    return calls


def test_inside_the_block_the_array_and_its_slices_are_not_checked_again(count):
    ev = check_events(_events(), SIZE)
    assert count == [400]
    with validated(ev, SIZE):
        assert check_events(ev, SIZE) is ev
        assert check_events(ev[10:300], SIZE).shape == (290,)
        check_events(ev[399:], SIZE)
        check_events(ev, SensorSize(32, 32))  # a larger sensor: still in range
    assert count == [400]
    check_events(ev, SIZE)  # after the block: checked again
    assert count == [400, 400]


def test_other_arrays_are_checked_even_inside_the_block(count):
    ev = check_events(_events(), SIZE)
    with validated(ev, SIZE):
        bad = ev.copy()  # same values, own memory (writeable): not covered
        bad["x"][5] = SIZE.width
        with pytest.raises(ValueError, match="outside the sensor"):
            check_events(bad, SIZE)
        with pytest.raises(ValueError, match="outside the sensor"):
            check_events(ev, SensorSize(8, 12))  # a smaller sensor than the block's: checked
        check_events(ev[::2], SIZE)  # another step: checked (and fine)
    assert count == [400, 400, 400, 200]


def test_the_array_is_read_only_during_the_block_only():
    ev = check_events(_events(), SIZE)
    with validated(ev, SIZE):
        assert not ev.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            ev["t"][0] = 7
        with pytest.raises(ValueError, match="read-only"):
            ev[3:5]["x"] = 0  # through a slice too
    assert ev.flags.writeable
    ro = ev.copy()
    ro.flags.writeable = False
    with validated(ro, SIZE):
        pass
    assert not ro.flags.writeable  # a read-only array stays read-only
    with pytest.raises(ZeroDivisionError):
        with validated(ev, SIZE):
            1 / 0
    assert ev.flags.writeable and not getattr(_checks._VALIDATED, "stack", [])  # restored on errors too


def test_a_view_whose_base_was_locked_since_is_left_writeable_and_checked(count):
    """numpy cannot make such a view writeable again: the block leaves it alone (the stages check it)."""
    base = check_events(_events(), SIZE)
    view = base[:]
    base.flags.writeable = False  # the view stays writeable, but could not be made so again once locked
    assert count == [400]
    with validated(view, SIZE):
        assert view.flags.writeable
        check_events(view, SIZE)  # not covered by the block: checked
    assert view.flags.writeable and count == [400, 400]
    detect(view, SIZE)  # the pipeline runs (it used to fail restoring the flag)
    assert view.flags.writeable


def test_only_checked_event_arrays_are_accepted():
    with pytest.raises(TypeError, match="EVENT_DTYPE"):
        with validated(np.zeros(3), SIZE):
            pass


def test_the_marker_is_per_thread(count):
    ev = check_events(_events(), SIZE)
    seen = []
    with validated(ev, SIZE):
        th = threading.Thread(target=lambda: seen.append(check_events(ev, SIZE) is ev))
        th.start()
        th.join()
    assert seen == [True] and count == [400, 400]  # the other thread checked it itself


def test_detect_checks_the_events_once(count):
    """The built-in buffer and estimator on records: the buffer's first pass is the check (no separate O(n)
    pass, and a bad event still gets check_events' error, serially and with strips); another estimator: one
    check_events, its stages O(1)."""
    ev = _events(2000)
    ref = detect(ev, SIZE)
    assert count == []
    assert ev.flags.writeable
    for n_tiles in (1, 2):
        for field, value in (("x", SIZE.width), ("t", -1)):
            bad = ev.copy()
            bad[field][1500] = value
            with pytest.raises(ValueError) as want:
                check_events(bad, SIZE)
            count.clear()
            with pytest.raises(ValueError) as got:
                detect(bad, SIZE, n_tiles=n_tiles)
            assert str(got.value) == str(want.value) and count == [2000]  # (the message's own check)
    # same result as with every stage checking (the marker changes no output)
    count.clear()
    with validated(check_events(ev, SIZE), SIZE):
        again = detect(ev, SIZE)
    assert count == [2000] and again.lifetimes.tobytes() == ref.lifetimes.tobytes()
    count.clear()
    detect(ev, SIZE, method="mueggler", use_buffer=True)
    assert count == [2000]


def test_edge_frames_checks_once(count):
    ev = _events(2000)
    lt = detect(ev, SIZE).lifetimes
    count.clear()
    edge_frames(ev, lt, SIZE, np.arange(0, 50_000, 1000))
    assert count == [2000]


def test_streaming_detector_checks_each_chunk_once(count):
    ev = _events(3000)
    det = Detector(SIZE)
    out = [det.process(c)[0] for c in np.array_split(ev, 6)] + [det.flush()[0]]
    # none: the built-in stages check each chunk in the pass that copies it into the buffer's slots
    # (_stream_kernels._fill_slots; its errors are check_events', tests/detector/test_pipeline.py), and
    # the estimator and the image get the released columns
    assert count == []
    assert all(o.flags.writeable for o in out)
    bad = ev[:10].copy()
    bad["x"][3] = SIZE.width  # outside the sensor: refused with check_events' message (then it is called)
    with pytest.raises(ValueError, match="x"):
        Detector(SIZE).process(bad)
    assert count == [10]


def test_streaming_detector_checks_a_third_party_filters_output_once(count):
    from evedge.detector.buffer import EventBuffer
    from evedge.detector.protocols import METHODS

    class Other(EventBuffer):  # not the built-in class: its output is checked
        pass

    name = "tests.other_buffer"
    if name not in METHODS:
        METHODS.register(name, lambda size, **kw: Other(size), kind="filter", source="test")
    ev = _events(3000)
    det = Detector(SIZE, filter=name)
    released = [det.process(c)[0].size for c in np.array_split(ev, 6)]
    assert count == [x for r in released for x in (500, r)]  # each chunk, then what it released


def test_a_stage_that_writes_into_its_input_fails_loudly():
    from evedge.detector.intra import IntraPixelLifetime

    class Rude(IntraPixelLifetime):
        def process(self, events):
            events["t"][:] = 0
            return super().process(events)

    from evedge.detector.protocols import METHODS

    name = "tests.rude_estimator"
    if name not in METHODS:
        METHODS.register(name, lambda size, **kw: Rude(size), kind="estimator", source="test")
    ev = _events()
    before = ev.copy()
    with pytest.raises(ValueError, match="read-only"):
        detect(ev, SIZE, method=name, use_buffer=False)
    assert ev.flags.writeable and np.array_equal(ev, before)  # the caller's events: unchanged and writeable again
