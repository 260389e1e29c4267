"""The installed package works outside the checkout: build the wheel, install it into a fresh venv, run it.

Installing every dependency from PyPI would be slow, so the fresh venv gets the
wheel alone (``--no-deps``) and sees the project venv's site-packages through a
``.pth`` file (third-party packages only: the project's own editable finder is a
``.pth`` there, and ``.pth`` files of a directory added that way are not run).
The test asserts that ``evedge`` is imported from the new venv. The venv path and
the numba cache are fixed per checkout, so a rerun reuses the compiled kernels
(cold: about 15 s CPU; warm: about 3 s); the copy, wheel, venv and run folder are removed
afterwards, only that cache stays in the temporary directory.
"""

import hashlib
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "data" / "tiny_shapes.toml"


def _run(cmd, cwd, env, timeout=600):
    res = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert res.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{res.stdout}\n{res.stderr}"
    return res.stdout


def test_wheel_installs_and_runs_outside_the_checkout():
    base = Path(tempfile.gettempdir()) / f"evedge-wheel-test-{hashlib.sha1(str(ROOT).encode()).hexdigest()[:10]}"
    try:
        for sub in ("wheel", "venv", "run"):
            shutil.rmtree(base / sub, ignore_errors=True)
        (base / "run").mkdir(parents=True)
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
        env["NUMBA_CACHE_DIR"] = str(base / "numba")
        # build from a clean copy of the sources: a stale build/ of the checkout must not leak into the wheel
        src = base / "src"
        shutil.rmtree(src, ignore_errors=True)
        shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(".git", ".venv", "build", "dist", "*.egg-info",
                                                                 "__pycache__", ".pytest_cache", "tmp", "*_out"))
        _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", base / "wheel", src], base, env)
        wheels = list((base / "wheel").glob("evedge-*.whl"))
        assert len(wheels) == 1
        _run([sys.executable, "-m", "venv", "--without-pip", base / "venv"], base, env)
        py = base / "venv" / "bin" / "python"
        _run([sys.executable, "-m", "pip", "--python", py, "install", "-q", "--no-deps", "--no-index", wheels[0]], base, env)
        site = _run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], base, env).strip()
        deps = sysconfig.get_paths()["purelib"]
        (Path(site) / "evedge_test_deps.pth").write_text(deps + "\n")
        # evedge comes from the new venv, and its shipped scenes from the wheel's package data
        where = _run([py, "-c", "import evedge, evedge.bench.exp_similarity as s; print(evedge.__file__); "
                                "print(s.scene_path('shapes_translation')); print(s.shipped_scenes())"], base / "run", env)
        lines = where.splitlines()
        venv = str(base / "venv")
        assert lines[0].startswith(venv) and not lines[0].startswith(str(ROOT)), lines[0]
        assert lines[1].startswith(venv) and lines[1].endswith("evedge/scenes/shapes_translation.toml"), lines[1]
        assert "stripes" in lines[2]
        evedge = base / "venv" / "bin" / "evedge"
        run = base / "run"
        out = _run([evedge, "bench", "similarity", "--quick", "--scene", TINY, "-o", "sim", "--no-progress"], run, env)
        assert "results.csv" in out and (run / "sim" / "results.h5").exists()
        _run([evedge, "simulate", TINY, "-o", "tiny.h5"], run, env)
        _run([evedge, "detect", "tiny.h5", "-o", "det", "--at-frames", "--quiet"], run, env)
        out = _run([evedge, "grade", "tiny.h5", "-d", "det/detection.h5", "-o", "graded"], run, env)
        assert "median_rel_error" in out and (run / "graded" / "report.html").exists()
        _run([evedge, "info", "det/detection.h5"], run, env)
    finally:
        # rebuilt from scratch on every run anyway (removed first above): only the numba cache is kept
        for sub in ("wheel", "venv", "run", "src"):
            shutil.rmtree(base / sub, ignore_errors=True)
    assert sorted(p.name for p in base.iterdir()) == ["numba"]
