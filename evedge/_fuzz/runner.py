"""Run fuzz cases in child processes with an address-space and a time limit.

A worker process (``python -m evedge._fuzz.runner``) reads one case per line
(JSON) on stdin, calls the case's target on its input and answers one JSON
line. Many cases run in one worker; when a worker dies (a signal, an abort in
native code) or does not answer within the time limit, the case it was on is
classified ``crash`` or ``timeout`` and a fresh worker takes the next case.

Outcomes
--------
``ok``          the target returned (and its result passed the target's check)
``error``       the documented error type, naming the input file
``unnamed``     the documented error type, but the message does not name the file
``traceback``   any other exception (``BaseException`` included: a pyo3 panic)
``accepted``    returned, but the result differs from what a checked file must
                give (a corrupted project file read as a different recording)
``memory``      ``MemoryError`` under the address-space limit
``crash``       the worker died (signal or exit code)
``timeout``     no answer within the time limit

Everything but ``ok`` and ``error`` is a failure.
"""

from __future__ import annotations

import json
import os
import resource
import select
import signal
import subprocess
import sys
import time
import traceback
from dataclasses import dataclass, field

FAILURES = ("unnamed", "traceback", "accepted", "memory", "crash", "timeout")
OUTCOMES = ("ok", "error") + FAILURES


@dataclass(frozen=True)
class Limits:
    """Per-case resource limits of a worker process."""

    memory_bytes: int = 4 * 2**30
    time_s: float = 20.0

    def __post_init__(self):
        if self.memory_bytes < 2**28:
            raise ValueError(f"Limits.memory_bytes must be >= 256 MiB, got {self.memory_bytes}")
        if not self.time_s > 0:
            raise ValueError(f"Limits.time_s must be > 0, got {self.time_s}")


@dataclass
class Result:
    """What one case gave."""

    case_id: str
    target: str
    mutation: str
    outcome: str
    detail: str = ""


@dataclass
class Tally:
    """Counts per (target, outcome) and the failing cases."""

    counts: dict = field(default_factory=dict)
    failures: list = field(default_factory=list)

    def add(self, result: Result) -> None:
        per = self.counts.setdefault(result.target, dict.fromkeys(OUTCOMES, 0))
        per[result.outcome] += 1
        if result.outcome in FAILURES:
            self.failures.append(result)

    def total(self, outcome: str | None = None) -> int:
        return sum(per[outcome] if outcome else sum(per.values()) for per in self.counts.values())


# ---------------------------------------------------------------- worker side


def _where(tb) -> str:
    """The innermost frame inside the project, else the innermost frame."""
    frames = traceback.extract_tb(tb)
    mine = [f for f in frames if "/evedge/" in f.filename or "/sim/" in f.filename
            or "/detector/" in f.filename or "/bench/" in f.filename]
    f = (mine or frames or [None])[-1]
    return f"{os.path.basename(f.filename)}:{f.lineno}" if f else "?"


def _run_case(case: dict) -> dict:
    from .targets import SELF_TARGETS, TARGETS

    target = TARGETS.get(case["target"]) or SELF_TARGETS[case["target"]]
    path = case["path"]
    errors = target.error_types
    try:
        value = target.call(path)
        problem = target.check(value, case) if target.check else None
    except MemoryError:
        return {"outcome": "memory", "detail": f"MemoryError at {_where(sys.exc_info()[2])}"}
    except errors as err:
        message = str(err)
        # the input, or another file of the case that the message blames (a video's timestamps file)
        names = [path, os.path.basename(path)] + [os.path.join(os.path.dirname(path), n)
                                                  for n in case.get("also_named", ())]
        if any(name in message for name in names):
            return {"outcome": "error", "detail": message[:300]}
        return {"outcome": "unnamed", "detail": f"{type(err).__name__}: {message[:300]}"}
    except BaseException as err:  # noqa: BLE001 - a pyo3 PanicException is a BaseException
        if isinstance(err, (KeyboardInterrupt, SystemExit)):
            raise
        return {"outcome": "traceback",
                "detail": f"{type(err).__name__} at {_where(err.__traceback__)}: {str(err)[:300]}"}
    if problem:
        return {"outcome": "accepted", "detail": problem}
    return {"outcome": "ok", "detail": ""}


def worker_main() -> None:
    """The worker loop: protocol on the original stdout, library chatter to /dev/null."""
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    for line in sys.stdin:
        case = json.loads(line)
        answer = _run_case(case)
        answer["case_id"] = case["case_id"]
        proto.write(json.dumps(answer) + "\n")


# ---------------------------------------------------------------- parent side


class _Worker:
    def __init__(self, limits: Limits, env: dict):
        def limit():
            resource.setrlimit(resource.RLIMIT_AS, (limits.memory_bytes, limits.memory_bytes))
            resource.setrlimit(resource.RLIMIT_CORE, (0, 0))

        self.proc = subprocess.Popen(
            [sys.executable, "-m", "evedge._fuzz.runner"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL, preexec_fn=limit, env=env, text=True, bufsize=1,
        )

    def ask(self, case: dict, time_s: float) -> dict:
        self.proc.stdin.write(json.dumps(case) + "\n")
        self.proc.stdin.flush()
        ready, _, _ = select.select([self.proc.stdout], [], [], time_s)
        if not ready:
            self.kill()
            return {"outcome": "timeout", "detail": f"no answer in {time_s:g} s"}
        line = self.proc.stdout.readline()
        if not line:
            code = self.proc.wait()
            name = f"signal {signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
            return {"outcome": "crash", "detail": f"worker died: {name}"}
        return json.loads(line)

    def alive(self) -> bool:
        return self.proc.poll() is None

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.stdin.close()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.kill()


def run_cases(cases, limits: Limits = Limits(), progress=None) -> Tally:
    """Run ``cases`` (an iterable of :class:`~evedge._fuzz.corpus.Case`) and tally them.

    Parameters
    ----------
    cases : iterable of Case
        Each has ``case_id``, ``target``, ``mutation`` and ``materialise()``
        (writes the input, returns its path) and ``cleanup()``.
    limits : Limits
        Address space and time per case.
    progress : callable, optional
        Called with each :class:`Result`.

    Returns
    -------
    Tally
    """
    env = dict(os.environ, PYTHONHASHSEED="0", NUMBA_DISABLE_JIT=os.environ.get("NUMBA_DISABLE_JIT", "0"))
    tally = Tally()
    worker = None
    try:
        for case in cases:
            path = case.materialise()
            try:
                if worker is None or not worker.alive():
                    worker = _Worker(limits, env)
                start = time.monotonic()
                answer = worker.ask({"case_id": case.case_id, "target": case.target, "path": str(path),
                                     **case.extra}, limits.time_s)
                if answer["outcome"] in ("crash", "timeout"):
                    worker = None
                detail = answer.get("detail", "")
                if answer["outcome"] == "timeout":
                    detail += f" (waited {time.monotonic() - start:.1f} s)"
                result = Result(case.case_id, case.target, case.mutation, answer["outcome"], detail)
            finally:
                case.cleanup()
            tally.add(result)
            if progress is not None:
                progress(result)
    finally:
        if worker is not None:
            worker.close()
    return tally


if __name__ == "__main__":
    worker_main()
