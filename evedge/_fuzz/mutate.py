"""Mutations of file contents: bytes (truncate, flip, insert, zero) and text lines/numbers.

Every mutator takes the content and a :class:`numpy.random.Generator` and
returns ``(new_content, description)``; the description is short and
reproducible enough to read in a failure list.
"""

from __future__ import annotations

import re

import numpy as np

#: Numbers that break naive parsers: huge, tiny, non-finite, negative, int64 edges.
INTERESTING_NUMBERS = (
    "nan", "inf", "-inf", "-1", "0", "-0", "1e308", "-1e308", "1e-320", "1e400",
    "9223372036854775807", "9223372036854775808", "-9223372036854775809", "18446744073709551616",
    "2147483648", "65536", "32768", "-32769", "99999999999999999999999999", "0x10", "1_0", "+", "-",
    "1e6", "1.5", "", "NaN", "1e19", "9.3e12",
)

_NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


def truncate(data: bytes, rng) -> tuple[bytes, str]:
    n = int(rng.integers(0, max(1, len(data))))
    return data[:n], f"truncate@{n}"


def flip(data: bytes, rng) -> tuple[bytes, str]:
    if not data:
        return data, "flip(empty)"
    b = bytearray(data)
    k = int(rng.integers(1, 4))
    where = rng.integers(0, len(b), k)
    for i in where:
        b[i] ^= int(rng.integers(1, 256))
    return bytes(b), f"flip@{','.join(map(str, where.tolist()))}"


def bit(data: bytes, rng) -> tuple[bytes, str]:
    if not data:
        return data, "bit(empty)"
    b = bytearray(data)
    i = int(rng.integers(0, len(b)))
    b[i] ^= 1 << int(rng.integers(0, 8))
    return bytes(b), f"bit@{i}"


def zero_tail(data: bytes, rng) -> tuple[bytes, str]:
    n = int(rng.integers(0, max(1, len(data))))
    return data[:n] + bytes(len(data) - n), f"zero_tail@{n}"


def zero_range(data: bytes, rng) -> tuple[bytes, str]:
    if not data:
        return data, "zero(empty)"
    i = int(rng.integers(0, len(data)))
    n = int(rng.integers(1, 65))
    return data[:i] + bytes(min(n, len(data) - i)) + data[i + n:], f"zero@{i}+{n}"


def insert_bytes(data: bytes, rng) -> tuple[bytes, str]:
    i = int(rng.integers(0, len(data) + 1))
    n = int(rng.integers(1, 17))
    return data[:i] + rng.integers(0, 256, n, dtype=np.uint8).tobytes() + data[i:], f"insert@{i}+{n}"


def delete_bytes(data: bytes, rng) -> tuple[bytes, str]:
    i = int(rng.integers(0, max(1, len(data))))
    n = int(rng.integers(1, 17))
    return data[:i] + data[i + n:], f"delete@{i}+{n}"


def duplicate_range(data: bytes, rng) -> tuple[bytes, str]:
    i = int(rng.integers(0, max(1, len(data))))
    n = int(rng.integers(1, 257))
    return data[:i + n] + data[i:i + n] + data[i + n:], f"dup@{i}+{n}"


def overwrite_int(data: bytes, rng) -> tuple[bytes, str]:
    """Write an extreme 32/64-bit integer at a random 4-byte-aligned offset (sizes, counts)."""
    if len(data) < 8:
        return data, "int(short)"
    i = int(rng.integers(0, len(data) // 4 - 1)) * 4
    value = int(rng.choice([-1, -5, 0, 2**31 - 1, 2**31, 2**32 - 1, 2**30, 2**40, 2**62, 2**63 - 1, 7]))
    width = int(rng.choice([4, 8]))
    blob = (value % 2 ** (8 * width)).to_bytes(width, "little")
    return data[:i] + blob + data[i + width:], f"int{width * 8}@{i}={value}"


BYTE_MUTATORS = (truncate, flip, bit, zero_tail, zero_range, insert_bytes, delete_bytes, duplicate_range,
                 overwrite_int)


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def delete_line(data: bytes, rng) -> tuple[bytes, str]:
    lines = _lines(data)
    i = int(rng.integers(0, len(lines)))
    return b"\n".join(lines[:i] + lines[i + 1:]), f"del_line{i}"


def duplicate_line(data: bytes, rng) -> tuple[bytes, str]:
    lines = _lines(data)
    i = int(rng.integers(0, len(lines)))
    return b"\n".join(lines[:i + 1] + lines[i:]), f"dup_line{i}"


def swap_lines(data: bytes, rng) -> tuple[bytes, str]:
    lines = _lines(data)
    i, j = (int(v) for v in rng.integers(0, len(lines), 2))
    lines[i], lines[j] = lines[j], lines[i]
    return b"\n".join(lines), f"swap_lines{i},{j}"


_ODD_LINES = (b"", b"#", b"# \xff\xfe comment", b"\x00", b"1 2 3", b"1 2 3 4 5", b"a b c d", b" \t ",
              b"1e400 1 1 1", b"0.5 -1 -1 1", b"0.5 1 1 2", b"nan 1 1 1", b"0.1 1.5 1 0", b"\xef\xbb\xbf0 0 0 0",
              b"0.1 1 1 1 # tail", b"0.1\t1\t1\t1", b"0.1,1,1,1", b"\x0c", b"9e18 0 0 0", b"-9e12 0 0 0",
              b"0 images/../../../etc/passwd", b"0 images/frame_99999999.png", b"0.1 images/\x00x.png",
              b"1 /dev/zero", b"0 images", b"1e19 images/frame_00000000.png")


def insert_line(data: bytes, rng) -> tuple[bytes, str]:
    lines = _lines(data)
    i = int(rng.integers(0, len(lines) + 1))
    new = _ODD_LINES[int(rng.integers(0, len(_ODD_LINES)))]
    return b"\n".join(lines[:i] + [new] + lines[i:]), f"ins_line{i}={new[:20]!r}"


def replace_number(data: bytes, rng) -> tuple[bytes, str]:
    spans = [m.span() for m in _NUMBER.finditer(data[:200_000])]
    if not spans:
        return data, "num(none)"
    a, b = spans[int(rng.integers(0, len(spans)))]
    new = INTERESTING_NUMBERS[int(rng.integers(0, len(INTERESTING_NUMBERS)))].encode()
    return data[:a] + new + data[b:], f"num@{a}={new.decode()}"


def line_ends(data: bytes, rng) -> tuple[bytes, str]:
    kind = int(rng.integers(0, 3))
    new = (b"\r", b"\r\n", b"\n\n")[kind]
    return data.replace(b"\n", new), f"line_ends={new!r}"


def odd_bytes(data: bytes, rng) -> tuple[bytes, str]:
    """A NUL, a non-UTF-8 byte or a form feed at a random place."""
    i = int(rng.integers(0, len(data) + 1))
    new = (b"\x00", b"\xff", b"\xc3", b"\x0c", b"\x0b", b"\x1c", b"\xe2\x80\xa8")[int(rng.integers(0, 7))]
    return data[:i] + new + data[i:], f"odd@{i}={new!r}"


TEXT_MUTATORS = (delete_line, duplicate_line, swap_lines, insert_line, replace_number, replace_number,
                 line_ends, odd_bytes, truncate, flip)


def mutate(data: bytes, rng, mutators, max_stack: int = 3) -> tuple[bytes, str]:
    """Apply 1..``max_stack`` mutators drawn from ``mutators``."""
    steps = []
    for _ in range(int(rng.integers(1, max_stack + 1))):
        data, what = mutators[int(rng.integers(0, len(mutators)))](data, rng)
        steps.append(what)
    return data, "+".join(steps)
