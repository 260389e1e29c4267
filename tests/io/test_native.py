"""Failures of faery's compiled decoders (RuntimeError, Rust panics) become EventFileErrors; Ctrl-C does not."""

from __future__ import annotations

import pytest

from evedge.events import Recording, SensorSize, make_events
from evedge.io import EventFileError, read_events, write_events
from evedge.io._native import is_decoder_failure


class PanicException(BaseException):
    """Stands for pyo3's PanicException (a BaseException, named so)."""


def test_is_decoder_failure():
    assert is_decoder_failure(RuntimeError("x")) and is_decoder_failure(PanicException("boom"))
    assert not is_decoder_failure(KeyboardInterrupt()) and not is_decoder_failure(SystemExit(1))


@pytest.mark.parametrize("raised, caught", [(PanicException("index out of range"), True),
                                            (RuntimeError("bad"), True), (KeyboardInterrupt(), False)])
def test_decoder_errors_are_wrapped(tmp_path, monkeypatch, raised, caught):
    faery = pytest.importorskip("faery")
    path = write_events(tmp_path / "a.es", Recording(make_events([1], [1], [5], [1]), SensorSize(4, 4)))

    class Broken:
        def __init__(self, *args, **kwargs):
            pass

        def __iter__(self):
            raise raised

    monkeypatch.setattr(faery.file_decoder, "Decoder", Broken)
    if caught:
        with pytest.raises(EventFileError, match=rf"a.es: Event Stream data cannot be decoded in its first packet .*{raised}"):
            read_events(path)
    else:
        with pytest.raises(KeyboardInterrupt):
            read_events(path)


def test_truncated_aedat4_files_are_event_file_errors(tmp_path):
    # the aedat package's decoder on every truncation of a small file: an EventFileError each time
    pytest.importorskip("faery")
    good = write_events(tmp_path / "a.aedat4", Recording(make_events([1, 2], [1, 2], [5, 6], [1, 0]), SensorSize(4, 4)))
    data = bytearray(good.read_bytes())
    for cut in range(20, min(len(data), 400), 7):
        bad = tmp_path / "bad.aedat4"
        bad.write_bytes(bytes(data[:cut]))
        with pytest.raises(EventFileError, match="bad.aedat4"):
            read_events(bad)


def test_a_real_rust_panic_is_wrapped(tmp_path):
    # faery 0.7.1 panics ("not yet implemented") on EVT 2.1 data: pyo3's PanicException, a BaseException
    pytest.importorskip("faery")
    from evedge.io._native import faery_decode

    path = tmp_path / "a.raw"
    path.write_bytes(b"% evt 2.1\n% geometry 40x6\n" + bytes(range(16)))
    with pytest.raises(EventFileError, match=r"a.raw: EVT 2.1 data cannot be decoded.*not yet implemented"):
        faery_decode(path, "EVT 2.1", "evt", dimensions=(40, 6), version="evt2.1")
    with pytest.raises(EventFileError, match=r"a.raw: EVT 2.1 files are not supported"):
        read_events(path)
