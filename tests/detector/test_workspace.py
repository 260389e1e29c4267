"""The workspace lending large scratch arrays between calls (:mod:`evedge.detector._workspace`)."""

import threading
import time

import numpy as np
import pytest

from evedge.detector._workspace import WORKSPACE, Workspace


def test_a_buffer_returns_to_the_cache_and_is_lent_again():
    ws = Workspace(min_bytes=0)
    with ws.scope() as take:
        a = take.empty((4, 5), np.float64)
        assert a.shape == (4, 5) and a.dtype == np.float64 and a.flags.c_contiguous
        a[:] = 7.0
        assert ws.cached_bytes == 0  # lent, not free
    assert ws.cached_bytes == 160
    with ws.scope() as take:
        b = take.empty(20, np.float64)
        assert np.shares_memory(a, b)
        assert np.all(b == 7.0)  # empty: the last user's contents
        c = take.empty(20, np.float64)  # the cached buffer is lent: a new one
        assert not np.shares_memory(b, c)
    assert ws.cached_bytes == 320


def test_zeros_clears_a_reused_buffer():
    ws = Workspace(min_bytes=0)
    with ws.scope() as take:
        take.empty(100, np.int64)[:] = -1
    with ws.scope() as take:
        z = take.zeros((10, 10), np.int64)
        assert z.shape == (10, 10) and not z.any()


def test_a_request_takes_the_smallest_fitting_buffer_at_most_twice_its_size():
    ws = Workspace(min_bytes=0)
    with ws.scope() as take:
        big = take.empty(1000, np.uint8)
        mid = take.empty(300, np.uint8)
    with ws.scope() as take:
        small = take.empty(100, np.uint8)  # 300 > 2 x 100 and 1000 too: a new buffer
        assert not np.shares_memory(small, mid) and not np.shares_memory(small, big)
        m = take.empty(250, np.uint8)  # 300 <= 500: the middle one, not the large one
        assert np.shares_memory(m, mid)
        assert np.shares_memory(take.empty(600, np.uint8), big)  # 1000 <= 1200
    assert ws.cached_bytes == 1000 + 300 + 100


def test_dtypes_and_shapes_are_views_of_one_buffer():
    ws = Workspace(min_bytes=0)
    with ws.scope() as take:
        take.empty(64, np.uint8)
    with ws.scope() as take:
        a = take.empty((4, 8), np.int8)  # 32 bytes: the 64-byte buffer (at most twice the request)
        assert a.dtype == np.int8 and a.shape == (4, 8)
    with ws.scope() as take:
        b = take.empty(8, np.float64)  # 64 bytes: the same buffer, another view
        assert b.dtype == np.float64 and np.shares_memory(a, b)
        assert take.empty(0, np.float64).shape == (0,)


def test_small_requests_are_not_cached():
    ws = Workspace(min_bytes=1024)
    with ws.scope() as take:
        a = take.empty(100, np.float64)  # 800 bytes
        a[:] = 1
    assert ws.cached_bytes == 0


def test_the_cache_is_bounded_and_drops_its_largest_buffers_first():
    ws = Workspace(max_cached_bytes=1500, min_bytes=0)
    with ws.scope() as take:
        take.empty(1000, np.uint8)
        take.empty(400, np.uint8)
        take.empty(300, np.uint8)
    assert ws.cached_bytes == 700  # 1700 > 1500: the 1000-byte buffer dropped
    ws.clear()
    assert ws.cached_bytes == 0


def test_buffers_return_when_the_scope_raises():
    ws = Workspace(min_bytes=0)
    with pytest.raises(RuntimeError):
        with ws.scope() as take:
            take.empty(10, np.float64)
            raise RuntimeError("inside")
    assert ws.cached_bytes == 80


def test_concurrent_scopes_get_distinct_buffers():
    ws = Workspace(min_bytes=0)
    with ws.scope() as take:  # a few cached buffers to fight over
        for _ in range(4):
            take.empty(4096, np.uint8)
    errors = []

    def worker(k):
        try:
            for _ in range(200):
                with ws.scope() as take:
                    a = take.empty(4096, np.uint8)
                    a[:] = k
                    time.sleep(0)  # let the other threads take and write their buffers meanwhile
                    if not np.all(a == k):
                        errors.append(k)
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert errors == []


def test_the_strips_leave_their_scratch_in_the_process_workspace():
    from evedge.detector import estimate_lifetimes
    from evedge.events import EVENT_DTYPE

    rng = np.random.default_rng(3)
    n = 200_000  # the strips' per-event slots exceed the workspace's 1 MiB threshold
    ev = np.zeros(n, EVENT_DTYPE)
    ev["x"] = rng.integers(0, 64, n)
    ev["y"] = rng.integers(0, 64, n)
    ev["t"] = np.sort(rng.integers(0, 2_000_000, n))
    ev["p"] = rng.integers(0, 2, n)
    WORKSPACE.clear()
    first = estimate_lifetimes(ev, (64, 64), n_tiles=2)
    kept = WORKSPACE.cached_bytes
    assert kept > 0
    again = estimate_lifetimes(ev, (64, 64), n_tiles=2)  # on reused (dirty) buffers
    assert WORKSPACE.cached_bytes == kept  # the same buffers lent again, none added
    assert first.tobytes() == again.tobytes() == estimate_lifetimes(ev, (64, 64)).tobytes()
    from evedge.detector import free_scratch

    assert free_scratch() == kept and WORKSPACE.cached_bytes == 0


def test_a_lease_returns_when_its_owner_is_collected():
    ws = Workspace(min_bytes=0)

    class Owner:
        pass

    owner = Owner()
    a = ws.lease((8, 8), np.float64, owner)
    assert a.shape == (8, 8) and ws.cached_bytes == 0
    del owner  # (reference counting: collected here)
    assert ws.cached_bytes == 512
    with ws.scope() as take:
        assert np.shares_memory(take.empty(64, np.float64), a)


def test_the_module_examples_run():
    import doctest

    from evedge.detector import _workspace

    result = doctest.testmod(_workspace)
    assert result.attempted >= 5 and result.failed == 0
