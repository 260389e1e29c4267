"""Calling the compiled (Rust) decoders and encoders of faery without letting their failures out.

faery raises ``RuntimeError`` on most bad input, but a Rust panic surfaces
as pyo3's ``PanicException``, which derives from ``BaseException`` (a fuzz
of damaged AEDAT 4 headers hit one; EVT 2.1 data always does): both become
an :class:`EventFileError` naming the file. In a fuzz of 300 damaged files
(truncated, bytes overwritten; 60 per EVT 2/EVT 3/DAT/ES/AEDAT 4, each
decoded in a child process) faery raised or decoded, never aborted the
process, so decoding runs in-process.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..events import FAERY_DTYPE, Recording, to_faery
from ._atomic import atomic_path, check_output_file
from ._checks import EventFileError


def is_decoder_failure(err: BaseException) -> bool:
    """True for an ordinary exception or a Rust panic; False for KeyboardInterrupt/SystemExit."""
    return isinstance(err, Exception) or type(err).__name__ == "PanicException"


def faery_decode(path: Path, label: str, file_type: str, *, dimensions: tuple[int, int] | None = None,
                 version: str | None = None) -> np.ndarray:
    """All events of ``path`` through ``faery.file_decoder.Decoder``, as one :data:`FAERY_DTYPE` array.

    Raises
    ------
    EventFileError
        On any failure of the decoder, with the number of events decoded before it.
    """
    import faery  # the compiled decoders; only these formats need it

    chunks: list[np.ndarray] = []
    n = 0
    try:
        kwargs = {"dimensions_fallback": dimensions} if dimensions is not None else {}
        decoder = faery.file_decoder.Decoder(path, file_type=file_type, version_fallback=version, **kwargs)
        for chunk in decoder:
            chunks.append(np.asarray(chunk))
            n += len(chunk)
    except BaseException as err:
        if not is_decoder_failure(err):
            raise
        where = f"after {n} good events" if n else "in its first packet"
        raise EventFileError(f"{path}: {label} data cannot be decoded {where} (corrupt or truncated file, "
                             f"or the wrong sensor size?): {err}") from None
    if not chunks:
        return np.empty(0, dtype=FAERY_DTYPE)
    return np.concatenate([c.astype(FAERY_DTYPE, copy=False) for c in chunks])


def faery_encode(path: Path, recording: Recording, label: str, file_type: str, *, version: str | None = None,
                 zero_t0: bool = False, who: str) -> Path:
    """Write the events of ``recording`` with faery's encoder, atomically.

    Raises
    ------
    ValueError
        When the events cannot be held (negative coordinates or times), or
        the encoder fails; the target is left untouched.
    """
    import faery

    path = Path(path)
    check_output_file(path, who)
    try:
        events = to_faery(recording.events)
    except ValueError as err:
        raise ValueError(f"{who}: {path}: {label} cannot hold these events: {err}") from None
    dims = (recording.sensor_size.width, recording.sensor_size.height)
    with atomic_path(path) as tmp:
        try:
            stream = faery.events_stream_from_array(events, dimensions=dims)
            stream.to_file(tmp, version=version, zero_t0=zero_t0, file_type=file_type)
        except BaseException as err:
            if not is_decoder_failure(err):
                raise
            raise ValueError(f"{who}: {path}: the {label} encoder failed: {err}") from None
    return path
