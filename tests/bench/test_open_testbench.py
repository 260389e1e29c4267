"""The README's example method, taken from the README text, through evedge detect, bench and grade."""

import re
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from evedge.bench.results import read_results
from evedge.cli import main

ROOT = Path(__file__).resolve().parents[2]
TINY = ROOT / "tests" / "data" / "tiny_shapes.toml"
TARGET = "neighbour_delay:NeighbourDelay"
DISPLAY_NAME = "neighbour delay (example plug-in)"


def readme_example() -> str:
    text = (ROOT / "README.md").read_text()
    m = re.search(r"<!-- example: neighbour_delay\.py -->\s*```python\n(.*?)```", text, re.S)
    assert m, "the README lost its example method"
    return m.group(1)


@pytest.fixture(scope="module")
def plugin(tmp_path_factory):
    folder = tmp_path_factory.mktemp("plugin")
    code = readme_example()
    assert 25 <= len(code.splitlines()) <= 45  # "about 30 lines"
    (folder / "neighbour_delay.py").write_text(code)
    from evedge.detector.protocols import METHODS

    assert TARGET not in METHODS.names()
    sys.path.insert(0, str(folder))
    yield folder
    sys.path.remove(str(folder))
    sys.modules.pop("neighbour_delay", None)
    # METHODS.get registers the target on first use: leave no plug-in behind for the tests that follow
    METHODS._entries.pop(TARGET, None)
    assert TARGET not in METHODS.names()


def _run(args):
    res = CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)
    assert res.exit_code == 0, res.output
    return res.output


def test_readme_example_through_detect_bench_and_grade(plugin, tmp_path):
    from evedge.detector.protocols import METHODS

    entry = METHODS.get(TARGET)
    assert entry.kind == "estimator" and entry.display_name == DISPLAY_NAME
    data = tmp_path / "tiny.h5"
    _run(["simulate", TINY, "-o", data])
    # detect with the plug-in, then grade its output
    _run(["detect", data, "-o", tmp_path / "det", "--method", TARGET, "--at-frames", "--quiet"])
    _run(["grade", data, "-d", tmp_path / "det" / "detection.h5", "-o", tmp_path / "graded"])
    graded = read_results(tmp_path / "graded" / "grade.csv")
    assert graded.unique("method") == [TARGET]
    # the grade's numbers recomputed here from the plug-in's detection file and the simulator's truth
    from evedge.io import read_hdf5
    from evedge.io.detection import read_detection

    truth = read_hdf5(data).truth
    det = read_detection(tmp_path / "det" / "detection.h5")
    ok = truth["is_signal"] & np.isfinite(truth["lifetime_us"])
    est = np.where(det.lifetimes["valid"], det.lifetimes["lifetime_us"], np.nan)
    have = ok & np.isfinite(est)
    assert 0 < have.sum() < ok.sum()  # the plug-in estimates some events, not all
    assert graded.value(metric="share_estimated", reference="truth", section="all") == pytest.approx(
        have.sum() / ok.sum())
    assert graded.value(metric="median_rel_error", reference="truth", section="all") == pytest.approx(
        np.median(np.abs(est[have] / truth["lifetime_us"][have] - 1)))
    assert graded.query(metric="median_cdm", reference="exact", section="all")
    assert DISPLAY_NAME in (tmp_path / "graded" / "report.html").read_text()
    # the bench compares it beside the paper's methods, on a user's own scene file
    _run(["bench", "paper", "-o", tmp_path / "cmp", "--quick", "--only", "similarity", "--scene", TINY,
          "--method", TARGET, "--no-progress"])
    table = read_results(tmp_path / "cmp" / "results.h5")
    rows = table.query(method=TARGET, metric="cdm_median", dataset="tiny_shapes")
    assert {r["display"] for r in rows} == {"predecessor", "lifetime_only"}
    assert {r["section"] for r in rows} >= {"slow", "fast"}
    html = (tmp_path / "cmp" / "report.html").read_text()
    board = html[html.index("<h2>Leaderboard"):html.index("<h2>Do the paper")]
    assert DISPLAY_NAME in board and "proposed (intra-pixel-area)" in board and "<b>" in board
