"""``evedge simulate`` writes a readable recording."""

from pathlib import Path

import numpy as np
from click.testing import CliRunner

from evedge.io import read_events
from evedge.sim.cli import simulate

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def test_simulate_h5_roundtrip(tmp_path):
    out = tmp_path / "s.h5"
    res = CliRunner().invoke(simulate, [str(SCENES / "stripes.toml"), "-o", str(out), "--duration", "0.01",
                                        "--seed", "3", "--quiet"])
    assert res.exit_code == 0, res.output
    rec = read_events(out)
    assert rec.events.shape[0] > 100
    assert rec.truth is not None and set(rec.truth.dtype.names) >= {"lifetime_us", "is_signal"}
    sig = rec.truth["is_signal"]
    np.testing.assert_allclose(np.unique(np.asarray(rec.truth["lifetime_us"])[sig]), [8000.0, 20000.0])
    assert rec.frames is not None and rec.edges is not None
    assert rec.metadata["seed"] == 3 and rec.metadata["scene_name"] == "stripes"


def test_simulate_ecd(tmp_path):
    out = tmp_path / "ecd"
    res = CliRunner().invoke(simulate, [str(SCENES / "stripes.toml"), "-o", str(out), "--duration", "0.005",
                                        "--format", "ecd", "--quiet"])
    assert res.exit_code == 0, res.output
    assert (out / "events.txt").stat().st_size > 0


def test_simulate_bad_scene_names_file_and_key(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[scene]\nkind = "stripes"\nduration_s = -1\n[sensor]\npreset = "dvs128"\n')
    res = CliRunner().invoke(simulate, [str(bad), "-o", str(tmp_path / "x.h5")])
    assert res.exit_code != 0
    assert "bad.toml" in res.output and "scene.duration_s" in res.output
