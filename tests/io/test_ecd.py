"""Event Camera Dataset text: parsing, every malformed-input error, and the folder writer."""

from __future__ import annotations

import numpy as np
import pytest

from evedge.events import Frames, Recording, SensorSize, make_events
from evedge.io import EventFileError, read_ecd, read_events, write_ecd

SIZE = SensorSize(240, 180)


def _write(tmp_path, text: str, name: str = "events.txt"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_parses_columns_and_rounds_seconds_to_microseconds(tmp_path):
    path = _write(tmp_path, "0.003811000 96 133 0\n0.0038200004 127 171 1\n0.003820501 4 160 1\n")
    rec = read_ecd(path, sensor_size=SIZE)
    assert rec.events["t"].tolist() == [3811, 3820, 3821]
    assert rec.events["x"].tolist() == [96, 127, 4]
    assert rec.events["y"].tolist() == [133, 171, 160]
    assert rec.events["p"].tolist() == [False, True, True]
    assert rec.metadata == {"source": str(path), "format": "ecd-text", "sensor_size_from": "option"}


def test_comments_and_blank_lines_are_skipped_and_lines_still_counted(tmp_path):
    text = "# header\n\n0.1 1 2 0\n# middle\n0.2 3 4 1  # trailing comment\nnan 5 6 1\n"
    path = _write(tmp_path, text)
    with pytest.raises(EventFileError, match=r"events\.txt: line 6: column 't' is nan"):
        read_ecd(path, sensor_size=SIZE)
    path.write_text(text.replace("nan 5 6 1\n", ""))
    assert read_ecd(path, sensor_size=SIZE).events["x"].tolist() == [1, 3]


@pytest.mark.parametrize("content, message", [
    pytest.param("0.1 1 2 0\n0.2 1 2 1\n0.3 1 abc 0\n", r"line 3: column 'y' is not a number: 'abc'",
                 id="malformed_token_names_line_and_column"),
    pytest.param("0.1 1 2 0\nt=0.2 1 2 1\n", r"line 2: column 't' is not a number", id="non_numeric_time"),
    pytest.param("0.1 1 2 0\n0.2 inf 2 1\n", r"line 2: column 'x' is inf \(not finite\)", id="inf"),
    pytest.param("0.1 1 2 0\n0.2 1 2 1 7\n0.3 1 2 1\n", r"line 2: expected 4 columns 't x y p', found 5",
                 id="wrong_column_count_on_one_line"),
    pytest.param("1 0.1 1 2 0\n2 0.2 1 2 1\n", r"line 1: expected 4 columns 't x y p', found 5",
                 id="wrong_column_count_on_every_line"),
    pytest.param("0.1 1 2 0\n0.2 1 2 1\n0.3 17",
                 r"line 3 \(the last line, no newline at the end: is the file truncated\?\)",
                 id="truncated_last_line_is_an_error_not_dropped"),
    pytest.param("0.1 1 2 0\n0.2 240 2 1\n", r"line 2: x=240 is outside the sensor 240x180 \(size from option\)",
                 id="x_out_of_range"),
    pytest.param("0.1 1 2 0\n0.2 1 -1 1\n", r"line 2: y=-1 is outside", id="y_out_of_range"),
    pytest.param("0.1 1 2 0\n0.2 1 2 -1\n", r"line 2: polarity p=-1, expected 0 or 1", id="polarity_not_0_or_1"),
    pytest.param("0.1 1.5 2 0\n", r"line 1: x=1.5 is not an integer", id="fractional_coordinate"),
    pytest.param(b"0.1 1 2 0\n0.2 \xff 2 1\n", r"line 2: not UTF-8 text \(byte 0xff at column 5\)", id="non_utf8_bytes"),
])
def test_bad_line_is_an_error_naming_the_line(tmp_path, content, message):
    path = tmp_path / "events.txt"
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    with pytest.raises(EventFileError, match=message):
        read_ecd(path, sensor_size=SIZE)


def test_last_line_without_newline_but_complete_is_read(tmp_path):
    path = _write(tmp_path, "0.1 1 2 0\n0.2 1 2 1")
    assert read_ecd(path, sensor_size=SIZE).events.size == 2


def test_unsorted_names_line_and_sort_option_sorts_stably(tmp_path):
    path = _write(tmp_path, "0.1 1 1 0\n0.3 2 2 1\n0.2 3 3 0\n0.2 4 4 1\n")
    with pytest.raises(EventFileError, match=r"line 3: timestamps are not sorted.*sort=True"):
        read_ecd(path, sensor_size=SIZE)
    rec = read_events(path, sensor_size=SIZE, sort=True)
    assert rec.events["x"].tolist() == [1, 3, 4, 2]  # equal times keep file order
    assert rec.metadata["sorted_on_load"] is True


@pytest.mark.parametrize("text", ["", "# only a comment\n\n"])
def test_empty_file_gives_zero_events(tmp_path, text):
    rec = read_ecd(_write(tmp_path, text), sensor_size=SIZE)
    assert rec.events.size == 0 and rec.sensor_size == SIZE


def test_unknown_sensor_size_asks_for_the_option(tmp_path):
    with pytest.raises(EventFileError, match=r"sensor size unknown.*--sensor WxH"):
        read_ecd(_write(tmp_path, "0.1 1 2 0\n"))


def _recording(n=200, frames_dtype=np.uint8, seed=1):
    rng = np.random.default_rng(seed)
    size = SensorSize(32, 24)
    ev = make_events(rng.integers(0, 32, n), rng.integers(0, 24, n),
                     np.sort(rng.integers(0, 3_000_000, n)), rng.integers(0, 2, n))
    if frames_dtype == np.uint8:
        images = rng.integers(0, 256, (3, 24, 32), dtype=np.uint8)
    else:
        images = rng.random((3, 24, 32))
    return Recording(ev, size, frames=Frames([0, 1_000_001, 2_500_000], images))


def test_folder_round_trip_with_frames(tmp_path):
    rec = _recording()
    folder = write_ecd(tmp_path / "seq", rec)
    assert sorted(p.name for p in folder.iterdir()) == ["events.txt", "images", "images.txt"]
    assert (folder / "images.txt").read_text().splitlines()[1] == "1.000001000 images/frame_00000001.png"
    back = read_events(folder)
    np.testing.assert_array_equal(back.events, rec.events)
    np.testing.assert_array_equal(back.frames.images, rec.frames.images)
    np.testing.assert_array_equal(back.frames.t_us, rec.frames.t_us)
    assert back.sensor_size == rec.sensor_size
    assert back.metadata["sensor_size_from"] == "frames"
    assert not list(folder.glob(".*tmp"))  # no temp files left behind


def test_writer_line_format_is_exact(tmp_path):
    ev = make_events([96, 5], [133, 6], [3811, 12_000_001], [0, 1])
    write_ecd(tmp_path, Recording(ev, SIZE))
    assert (tmp_path / "events.txt").read_text() == "0.003811000 96 133 0\n12.000001000 5 6 1\n"


def test_float_frames_are_quantised_to_uint8(tmp_path):
    rec = _recording(frames_dtype=np.float64)
    back = read_events(write_ecd(tmp_path, rec))
    np.testing.assert_array_equal(back.frames.images, np.rint(rec.frames.images * 255).astype(np.uint8))


def test_round_trip_without_frames_needs_the_sensor(tmp_path):
    rec = Recording(_recording().events, SensorSize(32, 24))
    folder = write_ecd(tmp_path, rec)
    with pytest.raises(EventFileError, match="sensor size unknown"):
        read_events(folder)
    np.testing.assert_array_equal(read_events(folder, sensor_size="32x24").events, rec.events)


def test_frames_smaller_than_event_coordinates_is_an_error(tmp_path):
    write_ecd(tmp_path, _recording())
    with open(tmp_path / "events.txt", "a") as fh:
        fh.write("5.0 40 3 1\n")
    with pytest.raises(EventFileError, match=r"line 201: x=40 is outside the sensor 32x24 \(size from frames\)"):
        read_events(tmp_path)


def test_sensor_option_disagreeing_with_frames_is_an_error(tmp_path):
    write_ecd(tmp_path, _recording())
    with pytest.raises(EventFileError, match=r"240x180 was given but the frames .* are 32x24"):
        read_events(tmp_path, sensor_size=SIZE)


def test_missing_frame_png_names_images_txt_line(tmp_path):
    write_ecd(tmp_path, _recording())
    (tmp_path / "images" / "frame_00000002.png").unlink()
    with pytest.raises(EventFileError, match=r"images\.txt: line 3: frame .*frame_00000002\.png does not exist"):
        read_events(tmp_path)


def test_folder_without_events_file(tmp_path):
    (tmp_path / "images.txt").write_text("")
    with pytest.raises(EventFileError, match=r"not an Event Camera Dataset folder: expected events\.txt"):
        read_events(tmp_path)


def test_folder_with_single_events_star_txt(tmp_path):
    _write(tmp_path, "0.1 1 2 0\n", name="events_chunk.txt")
    rec = read_events(tmp_path, sensor_size=SIZE)
    assert rec.metadata["source"].endswith("events_chunk.txt")


def test_writer_rejects_negative_times(tmp_path):
    ev = make_events([1], [1], [-5], [1])
    with pytest.raises(ValueError, match="timestamps >= 0"):
        write_ecd(tmp_path, Recording(ev, SIZE))


def test_time_beyond_int64_microseconds_names_the_line(tmp_path):
    # used to wrap to a negative time and pass the order check (np.diff overflowed too)
    path = _write(tmp_path, "0.1 1 1 1\n1e300 2 2 0\n")
    with pytest.raises(EventFileError, match=r"events\.txt: line 2: t=1e\+300 s is out of the int64 microsecond range"):
        read_ecd(path, sensor_size=SIZE)


def test_rewrite_without_frames_drops_the_old_frames(tmp_path):
    # a stale images.txt would make the folder read back with old frames and their sensor size
    write_ecd(tmp_path / "seq", _recording())
    rec = Recording(_recording().events, SensorSize(40, 30))
    folder = write_ecd(tmp_path / "seq", rec)
    assert sorted(p.name for p in folder.iterdir()) == ["events.txt"]
    with pytest.raises(EventFileError, match="sensor size unknown"):
        read_events(folder)


def test_rewrite_with_fewer_frames_leaves_no_old_png(tmp_path):
    write_ecd(tmp_path / "seq", _recording())
    rec = _recording()
    rec.frames = Frames(rec.frames.t_us[:1], rec.frames.images[:1])
    folder = write_ecd(tmp_path / "seq", rec)
    assert [p.name for p in (folder / "images").iterdir()] == ["frame_00000000.png"]
    assert len(read_events(folder).frames) == 1


def test_failed_write_leaves_the_old_folder_as_it_was(tmp_path):
    folder = write_ecd(tmp_path / "seq", _recording())
    before = {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    bad = _recording(frames_dtype=np.float64)
    bad.frames.images[2, 0, 0] = 1.5
    with pytest.raises(ValueError, match=r"float frames must lie in \[0, 1\]"):
        write_ecd(folder, bad)
    after = {p.relative_to(folder): p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    assert after == before
    assert not [p for p in folder.rglob("*") if p.name.startswith(".")]  # no temp left


def test_files_get_the_umask_mode_not_the_temp_files_0600(tmp_path):
    import os
    import stat

    mask = os.umask(0o022)
    try:
        folder = write_ecd(tmp_path / "seq", _recording())
    finally:
        os.umask(mask)
    for p in [folder / "events.txt", folder / "images.txt", folder / "images", *folder.glob("images/*")]:
        expected = 0o755 if p.is_dir() else 0o644
        assert stat.S_IMODE(p.stat().st_mode) == expected, p


def test_folder_path_that_is_a_file_or_foreign_images_folder(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError, match="it is an existing file"):
        write_ecd(tmp_path / "file", _recording())
    (tmp_path / "seq" / "images").mkdir(parents=True)
    (tmp_path / "seq" / "images" / "mine.jpg").write_text("keep")
    with pytest.raises(FileExistsError, match=r"images holds mine\.jpg, not frames written by write_ecd"):
        write_ecd(tmp_path / "seq", _recording())
    assert sorted(p.name for p in (tmp_path / "seq").rglob("*")) == ["images", "mine.jpg"]


def test_frame_path_not_utf8_names_the_line(tmp_path):
    _write(tmp_path, "0.1 1 1 1\n")
    (tmp_path / "images.txt").write_bytes(b"# frames\n0.1 images/\xff.png\n")
    with pytest.raises(EventFileError, match=r"images\.txt: line 2: frame path b'images/\\xff\.png' is not UTF-8 text"):
        read_events(tmp_path)


# ---------------------------------------------------------------- odd bytes and corrupt frames


@pytest.mark.parametrize("data, message", [
    pytest.param(b"0.1 1 2 0\r0.2 1 2 0\r0.3 1 2 7\r", r"line 3: polarity p=7", id="cr_only_line_ends"),
    pytest.param(b"0.1 1 2 0\r\n0.2 1 2 x\r\n", r"line 2: column 'p' is not a number", id="crlf"),
    pytest.param(b"# caf\xe9\n0.1 1 2 0\n", r"line 1: not UTF-8 text \(byte 0xe9 at column 6\)", id="latin1_comment"),
    pytest.param(b"0.1 1 2 0\n0.2 1\x00 2 0\n", r"line 2: holds a NUL byte \(column 6\)", id="nul_byte"),
])
def test_line_ends_and_odd_bytes_name_the_line(tmp_path, data, message):
    path = tmp_path / "events.txt"
    path.write_bytes(data)
    with pytest.raises(EventFileError, match=message):
        read_ecd(path, sensor_size=SensorSize(32, 24))


def _corrupt_png(tmp_path, change):
    write_ecd(tmp_path, _recording())
    png = tmp_path / "images" / "frame_00000001.png"
    png.write_bytes(change(png.read_bytes()))
    return tmp_path


def _rows_missing(data: bytes) -> bytes:
    import struct
    import zlib

    from PIL import Image
    import io

    img = np.asarray(Image.open(io.BytesIO(data)))
    raw = b"".join(b"\0" + row.tobytes() for row in img[:4])  # 4 of 24 rows, a valid zlib stream
    idat = zlib.compress(raw)
    chunk = lambda kind, body: struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    return data[:33] + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


@pytest.mark.parametrize("change, message", [
    pytest.param(lambda d: d[:-30] + bytes(30), r"fails its CRC|no IEND", id="zeroed_tail"),
    pytest.param(lambda d: d[:60], r"claims \d+ bytes past the end|cut short|no IEND", id="truncated"),
    pytest.param(lambda d: d[:40] + bytes([d[40] ^ 1]) + d[41:], r"fails its CRC", id="flipped_bit"),
    pytest.param(_rows_missing, r"pixel data holds \d+ bytes \(4 rows\) of the 792 bytes \(24 rows of 32\)",
                 id="rows_missing"),
    pytest.param(lambda d: b"GIF89a" + d[6:], r"not a PNG file", id="not_png"),
])
def test_corrupt_frames_are_errors_naming_the_frame(tmp_path, change, message):
    folder = _corrupt_png(tmp_path, change)
    with pytest.raises(EventFileError, match=rf"images\.txt: line 2: .*frame_00000001\.png: .*({message})"):
        read_ecd(folder)


def test_a_huge_declared_png_is_refused_before_decoding(tmp_path):
    import struct
    import zlib

    def bomb(data):
        header = struct.pack(">IIBBBBB", 30000, 30000, 8, 0, 0, 0, 0)
        chunk = lambda kind, body: struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
        return data[:8] + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(bytes(30001 * 10))) + chunk(b"IEND", b"")

    folder = _corrupt_png(tmp_path, bomb)
    with pytest.raises(EventFileError, match=r"frame_00000001\.png is 30000x30000, the first frame is 32x24"):
        read_ecd(folder)


@pytest.mark.parametrize("line, message", [
    pytest.param(b"0.5 ../../outside.png", r"frame path '../../outside.png' leaves the folder", id="dotdot"),
    pytest.param(b"0.5 /dev/zero", r"frame path '/dev/zero' leaves the folder", id="absolute"),
    pytest.param(b"0.5 images/fr\x00ame.png", r"line 2: holds a NUL byte", id="nul"),
    pytest.param(b"0.5 images", r"frame .*images is not a regular file", id="folder"),
])
def test_frame_paths_stay_in_the_folder(tmp_path, line, message):
    write_ecd(tmp_path, _recording())
    lines = (tmp_path / "images.txt").read_bytes().split(b"\n")
    lines[1] = line
    (tmp_path / "images.txt").write_bytes(b"\n".join(lines))
    with pytest.raises(EventFileError, match=message):
        read_ecd(tmp_path)


@pytest.mark.parametrize("name", ["images", "events.txt", "images.txt"])
def test_write_ecd_never_writes_through_a_link(tmp_path, name):
    folder = write_ecd(tmp_path / "seq", _recording())
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "frame_00000000.png").write_bytes(b"precious")  # a frame-named file write_ecd would replace
    target = victim if name == "images" else victim / "frame_00000000.png"
    p = folder / name
    if p.is_dir():
        for q in p.iterdir():
            q.unlink()
        p.rmdir()
    else:
        p.unlink()
    p.symlink_to(target)
    with pytest.raises(FileExistsError, match=f"seq/{name} is a symbolic link; it is not written through"):
        write_ecd(folder, _recording())
    assert sorted(victim.iterdir()) == [victim / "frame_00000000.png"]
    assert (victim / "frame_00000000.png").read_bytes() == b"precious"
