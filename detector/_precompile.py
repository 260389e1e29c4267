"""Cold start of ``evedge detect``: compile the estimator's kernels in a child process.

With an empty numba cache most of a short run is compilation (``benchmarks/bench_cli.py``
lists it: the intra-pixel estimator's stream kernel ``_intra_stream`` with its
callees ~4.5 s, the event buffer's ~1.3 s, the edge image's ~0.5 s on one core),
and numba compiles in one thread under one lock. :func:`start` therefore runs,
when the estimator's kernel is not in the cache, a child process that builds
the *same* estimator (the same parameters, hence the same argument types and the
same single specialisation) and feeds it a few synthetic events: numba compiles
it there and writes it to the cache (``NUMBA_CACHE_DIR`` is inherited), while
this process reads and checks the input, compiles the buffer and the edge
image and runs the buffer. :meth:`Ahead.wait`, called before the estimator's
first chunk, waits for the child; the estimator then loads its kernel from the
cache. On two free cores the cold part's wall time is about the estimator's
compilation alone instead of the sum. Nothing is compiled ahead with a warm
cache or when no core is free (:func:`start`), and nothing is pre-filled: an
empty cache stays a cold start.

The child's result is used only through numba's cache, which checks the source
stamp and the argument types itself: a child that fails or compiles something
else costs time, never a wrong result (the estimator then compiles in this
process, as without the child).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

from evedge.events import SensorSize

#: Most seconds to wait for the child before compiling in this process instead.
_WAIT_S = 300.0

#: The sensor of the child's synthetic events: the kernels' argument types do not depend on the
#: sensor's size (plain integers), so the child can start before the input's sensor is known.
SAMPLE_SENSOR = SensorSize(32, 32)


def _kernels(method: str):
    """The cached numba dispatchers whose compilation dominates ``method``'s cold start (empty: none known)."""
    if method == "intra":
        from ._intra_kernels import _intra_stream

        return [_intra_stream]
    if method == "mueggler":
        from ._mueggler_kernels import _mueggler_kernel

        return [_mueggler_kernel]
    return []


def is_cold(method: str) -> bool:
    """Whether numba's cache holds no compiled version of ``method``'s main kernel (fresh for its source).

    Reads the kernel's cache index (numba's own freshness rule: same numba version and
    source stamp). False when unknown (a method without known kernels, numba internals
    not as expected, caching off).
    """
    try:
        kernels = _kernels(method)
        for k in kernels:
            cache = getattr(k, "_cache", None)
            cache_file = getattr(cache, "_cache_file", None)
            if cache_file is None:  # caching disabled (e.g. NUMBA_DISABLE_JIT)
                return False
            if not cache_file._load_index():
                return True
    except Exception:  # noqa: BLE001 - numba internals changed: behave as without this module
        return False
    return False


class Ahead:
    """A running child compiling an estimator into the numba cache (see :func:`start`)."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.proc = proc

    def wait(self) -> bool:
        """Wait for the child (at most ``_WAIT_S``); True when it compiled without error."""
        if self.proc is None:
            return False
        try:
            rc = self.proc.wait(timeout=_WAIT_S)
        except subprocess.TimeoutExpired:
            self.close()
            return False
        finally:
            proc, self.proc = self.proc, None
            if proc is not None and proc.stdin is not None:
                proc.stdin.close()
        return rc == 0

    def close(self) -> None:
        """Stop the child if it still runs (the run ended early, e.g. on bad input)."""
        proc, self.proc = self.proc, None
        if proc is not None and proc.poll() is None:
            proc.kill()
            proc.wait()


def core_free() -> bool:
    """Whether a second core is idle on average (1-minute load average <= cores - 1, at least 2 cores)."""
    n = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except OSError:
        return False
    return n >= 2 and load <= n - 1


def start(method: str, sensor_size, params: dict | None) -> Ahead | None:
    """Start compiling ``method`` (with ``params``) in a child when the numba cache lacks it; else None.

    ``params`` is the mapping the caller passes to :func:`~evedge.detector.pipeline.make_method`
    (JSON values: numbers, booleans, strings). Environment ``EVEDGE_COMPILE_AHEAD``:
    ``0`` never, ``1`` whenever the cache lacks the kernel; unset: only when a core
    is free as well (:func:`core_free`). The child costs CPU (its own start, ~1.2 s:
    Python, numba and the package imported again) and gains wall time only on an
    idle core: on a loaded machine it would make the cold start slower.
    """
    mode = os.environ.get("EVEDGE_COMPILE_AHEAD", "")
    if mode == "0" or not is_cold(method) or (mode != "1" and not core_free()):
        return None
    try:
        spec = json.dumps({"method": method, "sensor": [int(sensor_size.width), int(sensor_size.height)],
                           "params": dict(params or {})})
    except (TypeError, ValueError):
        return None
    try:
        proc = subprocess.Popen([sys.executable, "-m", "evedge.detector._precompile"], stdin=subprocess.PIPE,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return None
    ahead = Ahead(proc)
    try:
        proc.stdin.write(spec.encode())
        proc.stdin.close()
    except OSError:  # the child is already gone
        ahead.close()
        return None
    return ahead


def sample_events(sensor_size, n: int = 64) -> np.ndarray:
    """``n`` time-sorted events spread over the sensor (two polarities): enough to call every stage once."""
    from evedge.events import make_events

    i = np.arange(n)
    return make_events(i % sensor_size.width, (i // 2) % sensor_size.height, 1000 + 10 * i, i % 2 == 0)


def _child() -> None:
    """The child: build the estimator as ``evedge detect`` does and run it on :func:`sample_events`."""
    from ._checks import validated
    from .pipeline import make_method

    spec = json.loads(sys.stdin.read())
    size = SensorSize(*spec["sensor"])
    est = make_method(spec["method"], size, spec["params"], kind="estimator")
    ev = sample_events(size)
    with validated(ev, size):  # as in evedge detect: the estimator gets checked, read-only chunks
        est.process(ev)


if __name__ == "__main__":
    _child()
