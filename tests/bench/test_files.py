"""Atomic writes: content and file mode."""


def test_atomic_writes_get_the_usual_file_mode(tmp_path):
    import os

    from evedge.bench._files import write_text_atomic

    mask = os.umask(0o022)
    try:
        p = write_text_atomic(tmp_path / "a.txt", "x")
    finally:
        os.umask(mask)
    assert p.read_text() == "x"
    assert p.stat().st_mode & 0o777 == 0o644
