"""summarize() against hand-counted answers, and the ``evedge info`` command."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from evedge.cli import main
from evedge.events import Recording, SensorSize, make_events
from evedge.io import summarize
from evedge.io.summary import peak_count


def test_summary_of_a_known_recording():
    # 4 events over 2 s; 3 of them within one 10 ms window; 3 ON
    ev = make_events([0, 1, 2, 3], [0, 0, 0, 0], [0, 1_000_000, 1_005_000, 2_000_000], [1, 1, 0, 1])
    truth = np.zeros(4, dtype=[("lifetime_us", "f8"), ("edge_id", "i4")])
    info = summarize(Recording(ev, SensorSize(4, 1), truth=truth, metadata={"source": "s", "format": "f",
                                                                             "sensor_size_from": "option"}))
    assert info["events"] == 4
    assert info["duration_s"] == 2.0 and info["t_first_us"] == 0 and info["t_last_us"] == 2_000_000
    assert info["mean_rate_ev_s"] == 2.0
    assert info["peak_rate_10ms_ev_s"] == 200.0  # 2 events in [1.000, 1.010) s
    assert (info["on_count"], info["off_count"], info["on_fraction"]) == (3, 1, 0.75)
    assert info["truth_fields"] == ["lifetime_us", "edge_id"] and info["frames"] == 0
    assert (info["sensor_width"], info["sensor_height"], info["sensor_size_from"]) == (4, 1, "option")
    json.dumps(info)  # serialisable


def test_peak_count_matches_brute_force():
    rng = np.random.default_rng(3)
    t = np.sort(rng.integers(0, 100_000, 300))
    brute = max(int(np.count_nonzero((t >= s) & (t < s + 10_000))) for s in t)
    assert peak_count(t, 10_000) == brute


def test_summary_of_empty_recording():
    info = summarize(Recording(make_events([], [], [], []), SensorSize(4, 4)))
    assert info["events"] == 0 and info["mean_rate_ev_s"] is None and info["on_fraction"] is None
    assert info["t_first_us"] is None and info["peak_rate_10ms_ev_s"] == 0.0


def test_info_on_stripes(realdata):
    path = realdata("rpg_event_lifetime/stripes.mat")
    result = CliRunner().invoke(main, ["info", str(path)])
    assert result.exit_code == 0, result.output
    assert "340,394" in result.output and "128x128 (from dvs128 .mat convention)" in result.output
    assert "1.197752 s" in result.output


def test_info_json_on_slider_depth(realdata):
    path = realdata("slider_depth/events_chunk.txt")
    result = CliRunner().invoke(main, ["info", str(path), "--json"])
    assert result.exit_code == 0, result.output
    info = json.loads(result.output)
    assert info["events"] == 50_000 and (info["sensor_width"], info["sensor_height"]) == (240, 180)
    assert info["frames"] == 87 and info["sensor_size_from"] == "frames"
    assert info["on_count"] + info["off_count"] == 50_000


def test_info_sensor_option_and_empty_file(tmp_path):
    path = tmp_path / "events.txt"
    path.write_text("")
    result = CliRunner().invoke(main, ["info", str(path), "--sensor", "240x180"])
    assert result.exit_code == 0, result.output
    assert "events     0" in result.output and "no events" in result.output


@pytest.mark.parametrize("args, message", [
    (["--sensor", "240by180"], "expected WIDTHxHEIGHT"),
    ([], "--sensor WxH"),
])
def test_info_errors_are_clean(tmp_path, args, message):
    path = tmp_path / "events.txt"
    path.write_text("0.1 1 2 0\n")
    result = CliRunner().invoke(main, ["info", str(path), *args])
    assert result.exit_code != 0
    assert message in result.output and "Traceback" not in result.output


def test_info_names_the_bad_line(tmp_path):
    path = tmp_path / "events.txt"
    path.write_text("0.1 1 2 0\n0.2 1 2\n")
    result = CliRunner().invoke(main, ["info", str(path), "--sensor", "dvs128"])
    assert result.exit_code == 1
    assert "line 2: expected 4 columns" in result.output
