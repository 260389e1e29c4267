"""The Event Camera Dataset text layout: ``events.txt``, ``images.txt``, ``images/``.

``events.txt`` holds one event per line, ``t x y p``, with ``t`` in float
seconds and ``p`` in {0, 1}; ``images.txt`` holds ``t images/frame_XXXXXXXX.png``
per line and the PNGs are 8-bit grey frames; ``calib.txt`` holds ``fx fy cx cy
k1 k2 p1 p2 k3`` (kept as ``Recording.calibration``, see :mod:`evedge.calibration`).
Comment lines start with ``#``.

Parsing is vectorised (:func:`numpy.loadtxt`, about 5 M lines/s here); the
slow per-line scan runs only after a failure, to name the first bad line.

References
----------
.. [1] E. Mueggler, H. Rebecq, G. Gallego, T. Delbruck, D. Scaramuzza, "The
       event-camera dataset and simulator", IJRR 36(2), 2017
       (rpg.ifi.uzh.ch/davis_data.html).
"""

from __future__ import annotations

import os
import re
import shutil
import warnings
import zlib
from pathlib import Path

import numpy as np

from .._resources import memory_shortfall
from ..calibration import CameraCalibration
from ..events import Frames, Recording, SensorSize, seconds_to_us
from ._atomic import atomic_path, current_umask, make_temp_dir
from ._checks import EventFileError, finish_events
from .registry import Format, register_format

_COLUMNS = ("t", "x", "y", "p")
_FRAME_NAME = re.compile(r"frame_\d{8}\.png")
_CHUNK_ROWS = 1_000_000


# ---------------------------------------------------------------- reading


def _split_lines(data: bytes) -> list[bytes]:
    """Lines as :func:`numpy.loadtxt` sees them: universal newlines (LF, CRLF and CR alone)."""
    return data.splitlines()


def _data_lines(data: bytes):
    """Yield ``(line_number, tokens)`` of every data line (1-based numbers)."""
    for number, raw in enumerate(_split_lines(data), start=1):
        tokens = raw.split(b"#", 1)[0].split()
        if tokens:
            yield number, tokens


def _line_of_row(data: bytes, row: int) -> str:
    """``"line N"`` of data row ``row`` (0-based), or ``"data row N"`` if the scan disagrees."""
    for k, (number, _) in enumerate(_data_lines(data)):
        if k == row:
            return f"line {number}"
    return f"data row {row + 1}"


def _first_bad_line(path: Path, data: bytes, ncols: int, names: tuple[str, ...]) -> str:
    """Name the first line that does not hold ``ncols`` numbers."""
    truncated = not data.endswith((b"\n", b"\r"))
    lines = _split_lines(data)
    last = len(lines)
    for number, raw in enumerate(lines, start=1):
        where = f"{path}: line {number}"
        try:
            raw.decode("utf-8")
        except UnicodeDecodeError as err:
            return f"{where}: not UTF-8 text (byte {raw[err.start]:#04x} at column {err.start + 1})"
        nul = raw.find(b"\0")
        if nul >= 0:
            return f"{where}: holds a NUL byte (column {nul + 1}): not a text file?"
        tokens = raw.split(b"#", 1)[0].split()
        if not tokens:
            continue
        if number == last and truncated:
            where += " (the last line, no newline at the end: is the file truncated?)"
        if len(tokens) != ncols:
            text = b" ".join(tokens).decode("utf-8", "replace")
            return f"{where}: expected {ncols} columns '{' '.join(names)}', found {len(tokens)}: {text!r}"
        for name, tok in zip(names, tokens):
            try:
                float(tok)
            except ValueError:
                text = tok.decode("utf-8", "replace")
                return f"{where}: column {name!r} is not a number: {text!r}"
    return ""


def _load_table(path: Path, ncols: int, names: tuple[str, ...]) -> np.ndarray:
    """Parse a whitespace table of numbers into an array ``(n, ncols)``."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            table = np.loadtxt(path, comments="#", dtype=np.float64, ndmin=2, encoding="utf-8")
    except (ValueError, UnicodeDecodeError) as err:
        message = _first_bad_line(path, path.read_bytes(), ncols, names)
        raise EventFileError(message or f"{path}: cannot parse as a table of numbers: {err}") from err
    if table.size == 0:
        return np.empty((0, ncols))
    if table.shape[1] != ncols:
        # every line has the same, wrong, number of columns
        raise EventFileError(_first_bad_line(path, path.read_bytes(), ncols, names))
    return table


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _adam7_bytes(width: int, height: int) -> int:
    """Filtered bytes of an interlaced 8-bit grey image: seven passes, one filter byte per row."""
    total = 0
    for x0, y0, dx, dy in ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)):
        cols, rows = -(-(width - x0) // dx), -(-(height - y0) // dy)
        if cols > 0 and rows > 0:
            total += rows * (cols + 1)
    return total


def verify_png(data: bytes, where: str, expect_shape: tuple[int, int] | None = None,
               expect_what: str = "expected") -> tuple[int, int]:
    """Check a PNG completely before it is decoded: chunk CRCs, header, the whole pixel stream.

    Parameters
    ----------
    data : bytes
        The file.
    where : str
        Prefix of messages (``"images.txt: line 3: images/frame_00000002.png"``).
    expect_shape : (height, width), optional
        Refuse another size before any pixel is decompressed.
    expect_what : str
        What ``expect_shape`` is, for the message (``"the first frame"``).

    Returns
    -------
    (width, height)

    Raises
    ------
    EventFileError
        Not a PNG, a chunk cut short or failing its CRC, not 8-bit grey,
        a size outside 1..32767, pixel data that does not decompress to
        exactly the rows the header declares (rows missing or extra), no
        ``IEND`` at the end.
    """
    if not data.startswith(_PNG_SIGNATURE):
        raise EventFileError(f"{where}: not a PNG file (no PNG signature)")
    pos, header, idat, ended = len(_PNG_SIGNATURE), None, [], False
    while pos < len(data):
        if pos + 12 > len(data):
            raise EventFileError(f"{where}: chunk at byte {pos} is cut short (truncated file?)")
        length = int.from_bytes(data[pos:pos + 4], "big")
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        if length > 2**31 - 1 or pos + 12 + length > len(data):
            raise EventFileError(f"{where}: chunk {kind!r} at byte {pos} claims {length} bytes past the end of the file")
        crc = int.from_bytes(data[pos + 8 + length:pos + 12 + length], "big")
        if zlib.crc32(kind + body) != crc:
            raise EventFileError(f"{where}: chunk {kind!r} at byte {pos} fails its CRC: the file is corrupt")
        if header is None and kind != b"IHDR":
            raise EventFileError(f"{where}: the first chunk is {kind!r}, expected IHDR")
        if kind == b"IHDR":
            if length != 13:
                raise EventFileError(f"{where}: IHDR of {length} bytes, expected 13")
            header = body
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            ended = True
            pos += 12 + length
            break
        pos += 12 + length
    if not ended:
        raise EventFileError(f"{where}: no IEND chunk: the file is truncated")
    width, height = int.from_bytes(header[0:4], "big"), int.from_bytes(header[4:8], "big")
    depth, colour, method, filtering, interlace = header[8:13]
    if (depth, colour) != (8, 0):
        raise EventFileError(f"{where}: a {depth}-bit PNG of colour type {colour}, expected 8-bit grey (type 0)")
    if not (1 <= width <= 32767 and 1 <= height <= 32767) or method or filtering or interlace > 1:
        raise EventFileError(f"{where}: bad PNG header ({width}x{height}, compression {method}, filter "
                             f"{filtering}, interlace {interlace})")
    if expect_shape is not None and (height, width) != tuple(expect_shape):
        raise EventFileError(f"{where} is {width}x{height}, {expect_what} is {expect_shape[1]}x{expect_shape[0]}")
    expected = _adam7_bytes(width, height) if interlace else height * (width + 1)
    inflater = zlib.decompressobj()
    try:
        raw = inflater.decompress(b"".join(idat), expected + 1)  # never more than the header allows
    except zlib.error as err:
        raise EventFileError(f"{where}: pixel data is corrupt: {err}") from None
    if len(raw) != expected or not inflater.eof:
        rows = len(raw) // (width + 1)
        what = "more than" if len(raw) > expected else f"{len(raw)} bytes ({rows} rows) of"
        raise EventFileError(f"{where}: pixel data holds {what} the {expected} bytes ({height} rows of "
                             f"{width}) its header declares: the file is corrupt")
    return width, height


def _read_frames(images_txt: Path) -> Frames:
    """Read ``images.txt`` and its PNGs into uint8 frames, each verified before it is decoded."""
    import io

    from PIL import Image  # Pillow is slow to import; only frames need it

    folder = images_txt.parent
    t_us, images = [], []
    raw_text = images_txt.read_bytes()
    entries = []
    for number, raw in enumerate(_split_lines(raw_text), start=1):
        where = f"{images_txt}: line {number}"
        if b"\0" in raw:
            raise EventFileError(f"{where}: holds a NUL byte: not a text file?")
        tokens = raw.split(b"#", 1)[0].split()
        if not tokens:
            continue
        if len(tokens) != 2:
            raise EventFileError(f"{where}: expected 't path', found {len(tokens)} columns")
        entries.append((where, tokens))
    for where, tokens in entries:
        try:
            t_s = float(tokens[0])
        except ValueError:
            raise EventFileError(f"{where}: time {tokens[0].decode('utf-8', 'replace')!r} is not a number") from None
        if not np.isfinite(t_s) or abs(t_s * 1e6) >= 2.0**63:
            raise EventFileError(f"{where}: time {t_s!r} is not finite or out of the int64 microsecond range")
        try:
            name = tokens[1].decode("utf-8")
        except UnicodeDecodeError:
            raise EventFileError(f"{where}: frame path {tokens[1]!r} is not UTF-8 text") from None
        relative = Path(name)
        if relative.is_absolute() or ".." in relative.parts:
            raise EventFileError(f"{where}: frame path {name!r} leaves the folder {folder}")
        png = folder / relative
        if not png.is_file():
            what = "does not exist" if not png.exists() else "is not a regular file"
            raise EventFileError(f"{where}: frame {png} {what}")
        try:
            data = png.read_bytes()
        except OSError as err:
            raise EventFileError(f"{where}: cannot read frame {png}: {err}") from err
        first = images[0].shape if images else None
        width, height = verify_png(data, f"{where}: frame {png}", first, "the first frame")
        if not images:
            short = memory_shortfall(len(entries) * width * height, f"{len(entries)} frames of {width}x{height}")
            if short:
                raise EventFileError(f"{images_txt}: {short}")
        try:
            with Image.open(io.BytesIO(data), formats=["PNG"]) as im:
                if im.mode != "L":
                    raise EventFileError(f"{where}: {png} is a {im.mode!r} image, expected 8-bit grey ('L')")
                img = np.asarray(im, dtype=np.uint8)
        except EventFileError:
            raise
        except Exception as err:  # noqa: BLE001 - Pillow raises OSError, SyntaxError, ValueError, bomb errors...
            raise EventFileError(f"{where}: cannot decode frame {png}: {type(err).__name__}: {err}") from None
        if img.shape != (height, width):
            raise EventFileError(f"{where}: frame {png} decoded to {img.shape[1]}x{img.shape[0]}, its header says "
                                 f"{width}x{height}")
        t_us.append(int(seconds_to_us(t_s)))
        images.append(img)
    if not images:
        raise EventFileError(f"{images_txt}: lists no frames")
    t = np.asarray(t_us, dtype=np.int64)
    dec = np.flatnonzero(t[1:] < t[:-1])
    if dec.size:
        raise EventFileError(f"{images_txt}: frame times decrease at frame {int(dec[0]) + 1}")
    return Frames(t, np.stack(images))


def find_events_txt(folder: Path) -> Path:
    """The events file of an ECD folder: ``events.txt``, else the only ``events*.txt``."""
    main = folder / "events.txt"
    if main.is_file():
        return main
    found = sorted(folder.glob("events*.txt"))
    if len(found) == 1:
        return found[0]
    listing = ", ".join(p.name for p in found) or "none"
    raise EventFileError(
        f"{folder}: not an Event Camera Dataset folder: expected events.txt "
        f"(or a single events*.txt), found {listing}"
    )


def read_ecd(path: str | os.PathLike, *, sensor_size: SensorSize | None = None, sort: bool = False) -> Recording:
    """Read Event Camera Dataset text (a file, or a folder holding ``events.txt``).

    Parameters
    ----------
    path : path-like
        ``events.txt`` (any name) or its folder. An ``images.txt`` beside it
        and its PNGs are read as frames.
    sensor_size : SensorSize, optional
        Needed when there are no frames; must match the frames when there are.
    sort : bool
        Sort by time (stable) instead of raising on decreasing timestamps.

    Returns
    -------
    Recording
        ``metadata`` holds ``source``, ``format`` (``"ecd-text"``) and
        ``sensor_size_from`` (``"frames"`` or ``"option"``).

    Raises
    ------
    EventFileError
        On any malformed line (named by number), non-finite values, polarity
        outside {0, 1}, unsorted timestamps (unless ``sort``), coordinates
        outside the sensor, or an unknown sensor size.
    """
    path = Path(path)
    if path.is_dir():
        path = find_events_txt(path)
    table = _load_table(path, 4, _COLUMNS)

    def locate(row: int) -> str:
        # error path only: re-read the file to turn a data row into a line number
        return _line_of_row(path.read_bytes(), row)

    t_s, x, y, p = table.T
    bad = np.flatnonzero(~np.isfinite(table).all(axis=1))
    if bad.size:
        i = int(bad[0])
        col = _COLUMNS[int(np.flatnonzero(~np.isfinite(table[i]))[0])]
        raise EventFileError(f"{path}: {locate(i)}: column {col!r} is {float(table[i, _COLUMNS.index(col)])} (not finite)")
    for name, col in (("x", x), ("y", y)):
        nonint = np.flatnonzero(col != np.rint(col))
        if nonint.size:
            i = int(nonint[0])
            raise EventFileError(f"{path}: {locate(i)}: {name}={float(col[i])} is not an integer pixel coordinate")
    badp = np.flatnonzero((p != 0) & (p != 1))
    if badp.size:
        i = int(badp[0])
        raise EventFileError(f"{path}: {locate(i)}: polarity p={float(p[i]):g}, expected 0 or 1")

    try:
        t_us = seconds_to_us(t_s)
    except ValueError:
        i = int(np.flatnonzero(np.abs(np.rint(t_s * 1e6)) >= 2.0**63)[0])
        raise EventFileError(f"{path}: {locate(i)}: t={float(t_s[i])!r} s is out of the int64 microsecond range") from None

    frames = None
    images_txt = path.parent / "images.txt"
    if images_txt.is_file():
        frames = _read_frames(images_txt)
        frame_size = SensorSize(frames.images.shape[2], frames.images.shape[1])
        if sensor_size is not None and sensor_size != frame_size:
            raise EventFileError(
                f"{path}: sensor size {sensor_size.width}x{sensor_size.height} was given but the "
                f"frames in {images_txt} are {frame_size.width}x{frame_size.height}"
            )
        sensor_size, size_from = frame_size, "frames"
    elif sensor_size is not None:
        size_from = "option"
    else:
        raise EventFileError(
            f"{path}: sensor size unknown: no images.txt with frames beside the events; pass it "
            f"(read_events(..., sensor_size=SensorSize(240, 180)), CLI: --sensor WxH, e.g. --sensor 240x180)"
        )
    events, was_sorted = finish_events(
        path, x, y, t_us, p > 0, sensor_size, size_from, locate, sort
    )
    metadata = {"source": str(path), "format": "ecd-text", "sensor_size_from": size_from}
    if frames is not None:
        metadata["frames_source"] = str(images_txt)
    calibration = None
    calib_txt = path.parent / "calib.txt"
    if calib_txt.is_file():
        try:
            calibration = CameraCalibration.read(calib_txt)
        except ValueError as err:
            raise EventFileError(str(err)) from None
        metadata["calibration_source"] = str(calib_txt)
    if was_sorted:
        metadata["sorted_on_load"] = True
    return Recording(events, sensor_size, frames=frames, metadata=metadata, calibration=calibration)


# ---------------------------------------------------------------- writing


def _format_seconds(t_us: np.ndarray) -> np.ndarray:
    """Columns ``(seconds, microseconds)``: exact decimal seconds without float rounding."""
    return np.stack([t_us // 1_000_000, t_us % 1_000_000], axis=1)


def _frames_as_uint8(frames: Frames) -> np.ndarray:
    images = frames.images
    if images.dtype == np.uint8:
        return images
    if images.dtype.kind == "f":
        if images.size and (not np.all(np.isfinite(images)) or images.min() < 0 or images.max() > 1):
            raise ValueError("write_ecd: float frames must lie in [0, 1]")
        return np.rint(images * 255.0).astype(np.uint8)
    raise TypeError(f"write_ecd: frames must be uint8 or float in [0, 1], got {images.dtype}")


def write_ecd(folder: str | os.PathLike, recording: Recording) -> Path:
    """Write a recording as an Event Camera Dataset folder.

    Writes ``events.txt`` (``%.9f %d %d %d``: seconds with 9 decimals, as the
    dataset does; exact, since times are whole microseconds), and, when the
    recording has frames, ``images.txt`` and ``images/frame_%08d.png``.

    Parameters
    ----------
    folder : path-like
        Created if missing. Other files in it are left alone.
    recording : Recording

    Returns
    -------
    Path
        The folder.

    Raises
    ------
    TypeError
        ``recording`` is not a :class:`Recording`, or its frames are neither
        uint8 nor float.
    ValueError
        Negative event or frame times, float frames outside [0, 1].
    NotADirectoryError
        ``folder`` is an existing file.
    FileExistsError
        ``folder/images`` holds files other than ``frame_XXXXXXXX.png``
        (not a folder this writer made; it is not replaced), or
        ``events.txt``, ``images.txt`` or ``images`` is a symbolic link.

    Notes
    -----
    Nothing is written until every check passed, and nothing is half-written:
    the PNGs go to a temp folder and each text file to a temp file, renamed
    into place at the end (``events.txt`` last). A previous recording's
    ``images.txt`` and ``images/`` in ``folder`` are replaced, or removed when
    this recording has no frames, so that reading the folder back never pairs
    these events with old frames.

    The layout has no place for the sensor size, ground truth or edge maps:
    without frames, read it back with ``sensor_size=``; keep truth in the
    HDF5 format (:func:`evedge.io.write_recording`). Float frames in [0, 1]
    are quantised to uint8.
    """
    if not isinstance(recording, Recording):
        raise TypeError(f"write_ecd: expected a Recording, got {type(recording).__name__}")
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise NotADirectoryError(f"write_ecd: cannot write a folder at {folder}: it is an existing file")
    ev = recording.events
    if ev.size and ev["t"].min() < 0:
        raise ValueError("write_ecd: the text format needs event timestamps >= 0")
    frames = recording.frames if recording.frames is not None and len(recording.frames) else None
    if frames is not None and frames.t_us.min() < 0:
        raise ValueError("write_ecd: the text format needs frame timestamps >= 0")
    images = _frames_as_uint8(frames) if frames is not None else None
    old_images = folder / "images"
    for name in ("events.txt", "images.txt", "images"):
        if (folder / name).is_symlink():  # it would be written, or replaced, through the link
            raise FileExistsError(f"write_ecd: {folder / name} is a symbolic link; it is not written through: "
                                  "choose another folder or remove it")
    if old_images.exists():
        foreign = [p.name for p in old_images.iterdir() if not _FRAME_NAME.fullmatch(p.name)] \
            if old_images.is_dir() else [old_images.name]
        if foreign:
            raise FileExistsError(
                f"write_ecd: {old_images} holds {', '.join(sorted(foreign)[:3])}, not frames written by "
                f"write_ecd; it would be replaced: choose another folder or remove it"
            )
    folder.mkdir(parents=True, exist_ok=True)

    def write_events(fh) -> None:
        for start in range(0, ev.size, _CHUNK_ROWS):
            chunk = ev[start:start + _CHUNK_ROWS]
            cols = np.column_stack([
                _format_seconds(chunk["t"]), chunk["x"], chunk["y"], chunk["p"].astype(np.int64)
            ]).astype(np.int64)
            # one %-format over the whole chunk runs in C, far faster than savetxt's row loop
            fh.write((("%d.%06d000 %d %d %d\n" * chunk.size) % tuple(cols.ravel().tolist())).encode())

    staged = None
    try:
        if images is not None:
            from PIL import Image

            staged = make_temp_dir(folder, "images")
            lines = []
            for k, (t, img) in enumerate(zip(frames.t_us, images)):
                name = f"frame_{k:08d}.png"
                Image.fromarray(img).save(staged / name, format="PNG")
                os.chmod(staged / name, 0o666 & ~current_umask())
                s, us = divmod(int(t), 1_000_000)
                lines.append(f"{s}.{us:06d}000 images/{name}\n")
        if recording.calibration is not None:
            with atomic_path(folder / "calib.txt") as calib_tmp:
                calib_tmp.write_text(" ".join(repr(v) for v in recording.calibration.as_list()) + "\n")
        else:
            # an old calib.txt must not be paired with these events on reading back
            (folder / "calib.txt").unlink(missing_ok=True)
        with atomic_path(folder / "events.txt") as events_tmp:
            with open(events_tmp, "wb") as fh:
                write_events(fh)
            if images is not None:
                with atomic_path(folder / "images.txt") as images_tmp:
                    images_tmp.write_bytes("".join(lines).encode())
                    # everything is on disk: swap in the PNGs, then images.txt and events.txt
                    # (renamed on leaving their blocks)
                    _replace_tree(staged, folder / "images")
                    staged = None
            else:
                _replace_tree(None, folder / "images")
                (folder / "images.txt").unlink(missing_ok=True)
    finally:
        if staged is not None:
            shutil.rmtree(staged, ignore_errors=True)
    return folder


def _replace_tree(new: Path | None, target: Path) -> None:
    """Put folder ``new`` at ``target`` (or just remove ``target`` when ``new`` is None)."""
    old = None
    if target.is_dir() and not target.is_symlink():
        old = make_temp_dir(target.parent, f"{target.name}.old")
        os.replace(target, old / target.name)
    if new is not None:
        os.replace(new, target)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _write_ecd_folder(path: Path, recording: Recording) -> Path:
    if path.suffix.lower() == ".txt":
        raise ValueError(
            f"{path}: the Event Camera Dataset format is a folder (events.txt, images.txt, images/); "
            f"give the folder, e.g. {path.with_suffix('')}"
        )
    return write_ecd(path, recording)


register_format(Format(
    "ecd", "Event Camera Dataset folder (events.txt [+ images.txt, images/, calib.txt])",
    extensions=(".txt",), read=read_ecd, write=_write_ecd_folder, folder=True, holds=("frames",),
))
