"""The shared numba splitmix64 against published outputs and a pure-Python reference."""

import numpy as np

from evedge._splitmix import GOLDEN, _splitmix64

M64 = (1 << 64) - 1


def _ref(x: int) -> int:
    z = (x + 0x9E3779B97F4A7C15) & M64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & M64
    return z ^ (z >> 31)


def test_first_outputs_of_the_seed_zero_stream():
    # the reference generator's state advances by GOLDEN before each output, starting at 0
    got = [int(_splitmix64(np.uint64(k * int(GOLDEN) & M64))) for k in range(4)]
    assert got == [0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, 0x06C45D188009454F, 0xF88BB8A8724C81EC]


def test_matches_python_reference_on_random_states():
    rng = np.random.default_rng(3)
    for x in rng.integers(0, 2**64, 200, dtype=np.uint64):
        assert int(_splitmix64(x)) == _ref(int(x))
