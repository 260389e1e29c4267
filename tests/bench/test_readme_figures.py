"""docs/make_readme_figures.py on a fake run directory: every figure, resampled, and missing ones named."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "docs" / "make_readme_figures.py"


@pytest.fixture(scope="module")
def script():
    spec = importlib.util.spec_from_file_location("make_readme_figures", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _png(path: Path, dpi: int):
    from evedge.bench._files import save_figure
    from evedge.bench._plot import pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(2, 1))
    ax.plot(np.arange(5), np.arange(5) ** 2)
    return save_figure(fig, path, dpi=dpi)


def _fake_run(tmp: Path, script, skip=()):
    for rel in script.COPIED.values():
        if rel not in skip:
            _png(tmp / rel, dpi=200)
    fm = {kind: {"no_intra": {"use_intra": False, "delta_px": 0.0, "noise_px": [0.0, 0.5],
                              "f_measure": [1.0, 0.5]},
                 "intra_delta_0.25": {"use_intra": True, "delta_px": 0.25, "noise_px": [0.0, 0.5],
                                      "f_measure": [1.0, None]}}
          for kind in ("global", "scattered")}
    (tmp / "results.json").write_text(json.dumps({"fmeasure": fm}))


def test_build_figures_writes_every_readme_png(script, tmp_path):
    from PIL import Image

    run = tmp_path / "run"
    _fake_run(run, script)
    written, missing = script.build_figures(run, tmp_path / "img")
    assert missing == {}
    assert sorted(p.name for p in written) == sorted(script.OUTPUTS)
    with Image.open(run / "qualitative" / "qualitative.png") as src, \
            Image.open(tmp_path / "img" / "qualitative.png") as dst:
        # 200 dpi -> 100 dpi: half the pixels each way, palette image
        assert abs(dst.width - src.width / 2) <= 1 and abs(dst.height - src.height / 2) <= 1
        assert dst.mode == "P"
    assert not list((tmp_path / "img").glob(".*.tmp"))  # atomic writes leave no temp file


def test_missing_inputs_are_named(script, tmp_path):
    run = tmp_path / "run"
    _fake_run(run, script, skip=(script.COPIED["lifetime_hist_stripes_real.png"],))
    (run / "results.json").write_text("{}")
    written, missing = script.build_figures(run, tmp_path / "img")
    assert set(missing) == {"lifetime_hist_stripes_real.png", "ransac_fmeasure.png"}
    assert len(written) == len(script.OUTPUTS) - 2
    assert script.main(["--from-run", str(run), "--out", str(tmp_path / "img2")]) == 1

