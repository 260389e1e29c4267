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


def test_a_failed_write_keeps_the_old_file_and_leaves_no_temp(tmp_path, monkeypatch):
    import os

    import numpy as np
    import pytest

    from evedge.bench import _files

    target = tmp_path / "results.json"
    _files.write_json_atomic(target, {"a": np.float64("nan"), "b": np.arange(2)})
    assert target.read_text() == '{\n  "a": null,\n  "b": [\n    0,\n    1\n  ]\n}\n'
    with pytest.raises(TypeError):  # not serialisable: fails before the file is touched
        _files.write_json_atomic(target, {"a": object()})

    def no_rename(src, dst):
        raise OSError("disk gone")

    monkeypatch.setattr(os, "replace", no_rename)
    with pytest.raises(OSError, match="disk gone"):
        _files.write_text_atomic(target, "half")
    assert '"a": null' in target.read_text()  # the old content, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.json"]  # the temp file was removed
