"""The format registry, write_events, `evedge convert` between every pair, and real sample files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.io
from click.testing import CliRunner

from evedge.cli import main
from evedge.events import Recording, SensorSize, make_events
from evedge.io import (EventFileError, Format, detect_format, formats, get_format, read_events, register_format,
                       write_events)
from evedge.io.registry import output_format

SENSOR = SensorSize(240, 180)
_rng = np.random.default_rng(7)
_N = 300
EVENTS = make_events(_rng.integers(0, 240, _N), _rng.integers(0, 180, _N),
                     np.sort(_rng.integers(0, 3_000_000, _N)), _rng.integers(0, 2, _N))


def _source(fmt: str, folder: Path, aedat2_file, aedat3_file, aedat2_address) -> Path:
    """A file of format ``fmt`` holding EVENTS: through evedge's writer, or encoded by hand."""
    rec = Recording(EVENTS, SENSOR)
    ev = EVENTS
    if fmt == "mat":
        path = folder / "src.mat"
        scipy.io.savemat(path, {"events": np.stack([ev["x"], ev["y"], np.where(ev["p"], 1, -1), ev["t"]], 1).astype(np.int32)})
        return path
    if fmt == "aedat2":
        _, davis = aedat2_address
        addr = [davis(239 - int(x), 179 - int(y), int(p)) for x, y, p in zip(ev["x"], ev["y"], ev["p"])]
        return aedat2_file(folder / "src.aedat", ["AEChip: eu.seebetter.ini.chips.davis.DAVIS240C"], addr, ev["t"])
    if fmt == "aedat3":
        events = [(int(x), int(y), int(p), 1, int(t)) for x, y, t, p in zip(ev["x"], ev["y"], ev["t"], ev["p"])]
        return aedat3_file(folder / "src.aedat", [(1, 0, events[:100]), (1, 0, events[100:])])
    ext = {"ecd": "", "hdf5": ".h5", "aedat4": ".aedat4", "evt3": ".raw", "evt2": ".raw", "dat": ".dat", "es": ".es"}[fmt]
    return write_events(folder / f"src{ext}", rec, format=fmt)


READABLE = sorted(n for n, f in formats().items() if f.read is not None)
WRITABLE = sorted(n for n, f in formats().items() if f.write is not None)


def test_every_format_is_registered():
    assert set(READABLE) == {"aedat2", "aedat3", "aedat4", "dat", "ecd", "es", "evt2", "evt3", "hdf5", "mat"}
    assert set(WRITABLE) == {"aedat4", "dat", "ecd", "es", "evt2", "evt3", "hdf5"}


def test_convert_every_pair(tmp_path, aedat2_file, aedat3_file, aedat2_address):
    pytest.importorskip("faery")
    runner = CliRunner()
    for src_fmt in READABLE:
        folder = tmp_path / src_fmt
        folder.mkdir()
        src = _source(src_fmt, folder, aedat2_file, aedat3_file, aedat2_address)
        assert detect_format(src) == src_fmt
        for dst_fmt in WRITABLE:
            dst = folder / f"out_{dst_fmt}"
            result = runner.invoke(main, ["convert", str(src), str(dst), "--format", dst_fmt, "--sensor", "240x180"])
            assert result.exit_code == 0, (src_fmt, dst_fmt, result.output)
            back = read_events(dst, format=dst_fmt, sensor_size=SENSOR if dst_fmt == "ecd" else None)
            assert back.events.tobytes() == EVENTS.tobytes(), (src_fmt, dst_fmt)
            assert back.sensor_size == SENSOR


def test_output_format_by_extension_and_errors(tmp_path):
    assert output_format("a.raw") == "evt3"
    assert output_format("a.aedat4") == "aedat4" and output_format("a.h5") == "hdf5"
    assert output_format(tmp_path / "folder") == "ecd"
    with pytest.raises(ValueError, match=r"cannot tell the output format from '.xyz'.*evt3 \(.raw\)"):
        output_format("a.xyz")
    with pytest.raises(ValueError, match=r"format='aedat2' is not a known format that can write; expected one of"):
        get_format("aedat2", need="write")
    rec = Recording(EVENTS, SENSOR)
    with pytest.raises(ValueError, match=r"the Event Camera Dataset format is a folder"):
        write_events(tmp_path / "events.txt", rec, format="ecd")
    result = CliRunner().invoke(main, ["convert", str(tmp_path / "missing.raw"), str(tmp_path / "o.h5")])
    assert result.exit_code == 1 and "missing.raw: no such file or directory" in result.output


def test_convert_says_what_it_drops(tmp_path):
    from evedge.events import Frames

    frames = Frames([0, 1000], np.zeros((2, 180, 240), np.uint8))
    src = write_events(tmp_path / "src.h5", Recording(EVENTS, SENSOR, frames=frames))
    result = CliRunner().invoke(main, ["convert", str(src), str(tmp_path / "o.raw")])
    assert result.exit_code == 0
    assert "note: evt3 holds events only here; not written: frames" in result.output
    assert read_events(tmp_path / "o.raw").metadata["format"] == "evt3"


def test_unknown_content_and_a_registered_plugin(tmp_path):
    odd = tmp_path / "x.bin"
    odd.write_bytes(b"MYFMT\n" + EVENTS.tobytes())
    with pytest.raises(EventFileError, match=r"x.bin: unknown event file type .* supported: "):
        read_events(odd)

    def read_my(path, *, sensor_size, sort):
        return Recording(np.frombuffer(Path(path).read_bytes()[6:], dtype=EVENTS.dtype).copy(), sensor_size or SENSOR,
                         metadata={"format": "myfmt"})

    register_format(Format("myfmt", "a test format", sniff=lambda head: head.startswith(b"MYFMT\n"), read=read_my))
    try:
        assert detect_format(odd) == "myfmt"
        assert read_events(odd).events.tobytes() == EVENTS.tobytes()
    finally:
        from evedge.io import registry
        registry._REGISTRY.pop("myfmt")


REALDATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "realdata"
_EXT = {"aedat4": ".aedat4", "dat": ".dat", "es": ".es", "evt2": ".raw", "evt3": ".raw", "hdf5": ".h5", "ecd": ""}


# ../shared/realdata holds no real .raw/.dat/.aedat/.aedat4/.es file (SOURCES.md: the upstream ones are
# LFS pointers or absent), so the new formats are checked on the real recordings that are there: each
# written in every writable format and read back unchanged; counts and time spans from SOURCES.md
@pytest.mark.parametrize("relative, n_events, t_span_us, sensor", [
    ("rpg_event_lifetime/stripes.mat", 340_394, (0, 1_197_752), SensorSize(128, 128)),
    ("slider_depth", 50_000, (3_811, 174_156), SensorSize(240, 180)),
])
def test_real_recordings_through_every_writable_format(tmp_path, realdata, relative, n_events, t_span_us, sensor):
    pytest.importorskip("faery")
    rec = read_events(realdata(relative))
    assert rec.events.size == n_events and rec.sensor_size == sensor
    assert (int(rec.events["t"][0]), int(rec.events["t"][-1])) == t_span_us
    assert set(WRITABLE) == set(_EXT)
    for fmt in WRITABLE:
        path = write_events(tmp_path / f"out_{fmt}{_EXT[fmt]}", rec, format=fmt)
        assert detect_format(path) == fmt
        back = read_events(path, format=fmt, sensor_size=sensor if fmt == "ecd" else None)
        assert back.events.tobytes() == rec.events.tobytes(), fmt
        assert back.sensor_size == sensor, fmt
