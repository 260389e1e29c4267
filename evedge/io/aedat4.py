"""AEDAT 4 files (iniVation DV) through the ``aedat`` package.

The ``aedat`` package (neuromorphicsystems/aedat, a Rust decoder) iterates the
file's packets; event packets hold structured arrays with fields ``t`` (uint64
microseconds), ``x``, ``y`` (uint16) and ``on`` (bool). The sensor size comes
from the event stream's description (``sizeX``, ``sizeY``).

References
----------
.. [1] iniVation, "AEDAT 4.0 file format", docs.inivation.com.
.. [2] A. Marcireau, ``aedat`` (PyPI), github.com/neuromorphicsystems/aedat.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..events import Frames, Recording, SensorSize
from ._checks import EventFileError, finish_events, locate_index
from ._isolated import DecoderError, run_isolated
from ._native import is_decoder_failure
from .registry import Format, register_format


def _decode(path: Path, sensor_size: SensorSize | None):
    """Decode in the child process: the first event stream's packets and its grey frames."""
    import aedat  # the compiled decoder; only AEDAT 4 needs it

    try:
        decoder = aedat.Decoder(str(path))
        streams = decoder.id_to_stream()
    except BaseException as err:  # a pyo3 PanicException is a BaseException
        if not is_decoder_failure(err):
            raise
        raise EventFileError(f"{path}: not a readable AEDAT4 file: {err}") from None
    event_ids = sorted(i for i, s in streams.items() if s.get("type") == "events")
    if not event_ids:
        kinds = sorted({s.get("type", "?") for s in streams.values()})
        raise EventFileError(f"{path}: AEDAT4 file has no event stream (streams: {', '.join(kinds)})")
    sid = event_ids[0]
    try:
        file_size = SensorSize(int(streams[sid]["width"]), int(streams[sid]["height"]))
    except KeyError as err:
        raise EventFileError(f"{path}: event stream {sid} has no {err.args[0]!r} in its description") from None
    except (TypeError, ValueError) as err:
        raise EventFileError(f"{path}: event stream {sid} has a bad sensor size: {err}") from None
    if sensor_size is not None and sensor_size != file_size:
        raise EventFileError(
            f"{path}: sensor size {sensor_size.width}x{sensor_size.height} was given but the file's "
            f"event stream {sid} is {file_size.width}x{file_size.height}"
        )
    chunks, frame_t, frame_images = [], [], []
    skipped: dict[str, int] = {}
    packet = 0
    try:
        for packet, content in enumerate(decoder):
            if "events" in content and content["stream_id"] == sid:
                chunks.append(content["events"])
            elif "frame" in content:
                frame = content["frame"]
                pixels = np.asarray(frame["pixels"])
                if frame["format"] == "L" and pixels.shape == file_size.shape:
                    frame_t.append(int(frame["t"]))
                    frame_images.append(pixels.astype(np.uint8))
                else:
                    key = f"frame {frame['format']} {pixels.shape[1]}x{pixels.shape[0]}"
                    skipped[key] = skipped.get(key, 0) + 1
            else:
                key = next((k for k in content if k != "stream_id"), "?")
                skipped[key] = skipped.get(key, 0) + 1
    except BaseException as err:  # a pyo3 PanicException is a BaseException
        if not is_decoder_failure(err) or isinstance(err, MemoryError):
            raise
        raise EventFileError(f"{path}: AEDAT4 packet {packet + 1} cannot be decoded (truncated or corrupt file?): {err}") from None
    return file_size, sid, chunks, frame_t, frame_images, skipped


def read_aedat4(path: str | os.PathLike, *, sensor_size: SensorSize | None = None, sort: bool = False) -> Recording:
    """Read the first event stream (and 8-bit grey frames) of an AEDAT 4 file.

    Parameters
    ----------
    path : path-like
    sensor_size : SensorSize, optional
        Must match the stream's description when given.
    sort : bool
        Sort by time (stable) instead of raising on decreasing timestamps.

    Returns
    -------
    Recording
        Timestamps as stored (absolute microseconds, as DV writes them);
        ``metadata["sensor_size_from"]`` is ``"file metadata"``.

    Raises
    ------
    EventFileError
        Unreadable or truncated file (the decoder's message is included),
        no event stream, coordinates outside the sensor, unsorted timestamps.

    Notes
    -----
    Frames are kept only when 8-bit grey (``"L"``) and sensor-sized; other
    frame formats and IMU/trigger packets are counted in ``metadata`` and
    skipped. The decoder runs in a forked child process
    (:func:`evedge.io._isolated.run_isolated`): a panic, an abort or a
    gigabyte reservation on a corrupt file is an :class:`EventFileError`.
    """
    import aedat  # noqa: F401 - the compiled decoder, imported once here rather than in each child

    path = Path(path)
    if path.is_dir():
        raise EventFileError(f"{path}: is a folder, not an AEDAT4 file")
    try:
        # the Rust decoder panics or aborts the process on some corrupt files: it runs in a child
        file_size, sid, chunks, frame_t, frame_images, skipped = run_isolated(
            path, "aedat (AEDAT4)", _decode, path, sensor_size)
    except DecoderError as err:
        raise EventFileError(f"{path}: not a readable AEDAT4 file: {err}") from None
    raw = np.concatenate(chunks) if chunks else np.empty(0, dtype=[("t", "<u8"), ("x", "<u2"), ("y", "<u2"), ("on", "?")])
    t = raw["t"]
    if t.size and int(t.max()) > np.iinfo(np.int64).max:
        raise EventFileError(f"{path}: timestamps exceed int64 microseconds")
    events, was_sorted = finish_events(
        path, raw["x"].astype(np.int64), raw["y"].astype(np.int64), t.astype(np.int64), raw["on"].astype(bool),
        file_size, "file metadata", locate_index, sort,
    )
    frames = Frames(np.asarray(frame_t, dtype=np.int64), np.stack(frame_images)) if frame_images else None
    metadata = {"source": str(path), "format": "aedat4", "sensor_size_from": "file metadata", "aedat4_event_stream": sid}
    if skipped:
        metadata["aedat4_skipped_packets"] = skipped
    if was_sorted:
        metadata["sorted_on_load"] = True
    return Recording(events, file_size, frames=frames, metadata=metadata)


def write_aedat4(path: str | os.PathLike, recording: Recording) -> Path:
    """Write the events of ``recording`` as AEDAT 4 (one LZ4-compressed event stream) through faery.

    Frames are not written: faery 0.7.1's encoder cannot build frame packets
    from Python. Atomic (temp file, then rename).

    Parameters
    ----------
    path : path-like
    recording : Recording

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        Negative coordinates or timestamps (AEDAT 4 stores them unsigned), or an encoder failure.

    Examples
    --------
    >>> from evedge.io import read_events, write_aedat4
    >>> write_aedat4("out.aedat4", read_events("slider_depth"))  # doctest: +SKIP
    """
    from ._native import faery_encode

    return faery_encode(Path(path), recording, "AEDAT 4", "aedat", who="write_aedat4")


register_format(Format(
    "aedat4", "AEDAT 4 (iniVation DV): events and 8-bit frames (written: events)",
    extensions=(".aedat4",), read=read_aedat4, write=write_aedat4,
    sniff=lambda head: head.startswith(b"#!AER-DAT4.0"),
))
