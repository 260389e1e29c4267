"""Run a native decoder in a forked child, so that its crash is an error, not ours.

scipy's ``.mat`` parser (C/Cython) segfaults on some corrupt files and the
``aedat`` decoder (Rust) aborts the process when a corrupt packet size makes
it reserve gigabytes; neither can be caught in-process. :func:`run_isolated`
forks, calls the decoder in the child under an address-space limit (the
machine's available memory), sends the result back pickled through a
temporary file and turns a signal, an exit or an exception in the child into
an :class:`EventFileError` naming the file.
"""

from __future__ import annotations

import faulthandler
import os
import pickle
import resource
import signal
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from .._resources import available_memory_bytes
from ._checks import EventFileError


def _wait(pid: int, timeout_s: float | None) -> int | None:
    """The child's wait status, or None after killing it when ``timeout_s`` passed."""
    if timeout_s is None:
        return os.waitpid(pid, 0)[1]
    deadline = time.monotonic() + timeout_s
    pause = 0.0005
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return status
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            return None
        time.sleep(pause)
        pause = min(pause * 2, 0.02)


class DecoderError(Exception):
    """Raised inside the child for a failure the decoder reported (the message is kept)."""


def run_isolated(path: Path, decoder: str, function: Callable, *args, timeout_s: float | None = None):
    """Call ``function(*args)`` in a forked child and return its (picklable) result.

    Parameters
    ----------
    path : Path
        The file being decoded, for messages.
    decoder : str
        Its name, for messages (``"scipy .mat"``).
    function : callable
        Runs in the child; an exception it raises comes back as its type name
        and message.
    timeout_s : float, optional
        Kill the child after this long (a corrupt size can make a parser loop
        for minutes) and raise.

    Returns
    -------
    object
        What ``function`` returned. An :class:`EventFileError` raised in the
        child is raised again as is; any other exception as :class:`DecoderError`.

    Raises
    ------
    EventFileError
        The child died of a signal or exited without a result, or ``function``
        raised (``BaseException`` included: a pyo3 ``PanicException``).
    """
    fd, out = tempfile.mkstemp(prefix=".evedge-decode-", suffix=".pkl")
    os.close(fd)
    limit = max(available_memory_bytes(), 2**30)
    try:
        pid = os.fork()
        if pid == 0:  # the child: never returns
            code = 1
            try:
                faulthandler.disable()  # a crash here is reported by the parent, not dumped to stderr
                soft, hard = resource.getrlimit(resource.RLIMIT_AS)
                if hard == resource.RLIM_INFINITY or limit < hard:
                    new_soft = limit if soft == resource.RLIM_INFINITY else min(soft, limit)
                    resource.setrlimit(resource.RLIMIT_AS, (new_soft, hard))
                resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
                try:
                    payload = ("ok", function(*args))
                except EventFileError as err:
                    payload = ("file", str(err))
                except MemoryError:
                    payload = ("error", "the decoder ran out of memory (a size in the file is corrupt?)")
                except BaseException as err:  # noqa: BLE001 - a pyo3 PanicException is a BaseException
                    payload = ("error", f"{type(err).__name__}: {err}")
                with open(out, "wb") as fh:
                    pickle.dump(payload, fh, protocol=5)
                code = 0
            finally:
                os._exit(code)
        status = _wait(pid, timeout_s)
        if status is None:
            raise EventFileError(f"{path}: the {decoder} parser did not finish within {timeout_s:g} s on this "
                                 f"file's structure: it is corrupt")
        if os.WIFSIGNALED(status):
            sig = signal.Signals(os.WTERMSIG(status)).name
            raise EventFileError(f"{path}: the {decoder} decoder crashed ({sig}) on this file: it is corrupt")
        try:
            with open(out, "rb") as fh:
                kind, value = pickle.load(fh)
        except (OSError, EOFError, pickle.UnpicklingError):
            raise EventFileError(f"{path}: the {decoder} decoder exited without a result "
                                 f"(status {os.waitstatus_to_exitcode(status)})") from None
    finally:
        Path(out).unlink(missing_ok=True)
    if kind == "file":
        raise EventFileError(value)
    if kind == "error":
        raise DecoderError(value)
    return value
