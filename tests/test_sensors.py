"""Sensor presets: defined once in evedge.sensors, every other table derives from it."""

import math

import pytest

from evedge.events import SENSOR_PRESETS, SensorSize
from evedge.sensors import SENSOR_MODELS, sensor_model

SIZES = {"dvs128": (128, 128), "davis240": (240, 180), "davis346": (346, 260), "dvxplorer": (640, 480),
         "gen3": (640, 480), "gen4": (1280, 720)}


def test_documented_resolutions_and_one_table():
    assert {k: (m.width, m.height) for k, m in SENSOR_MODELS.items()} == SIZES
    assert {k: (s.width, s.height) for k, s in SENSOR_PRESETS.items()} == SIZES
    for name, (w, h) in SIZES.items():
        assert SensorSize.parse(name.upper()) == SensorSize(w, h)


def test_documented_figures():
    d346 = sensor_model("davis346")
    # iniVation: 14.3 % ON, 22.5 % OFF contrast sensitivity -> log steps ln(1 + c)
    assert d346.contrast_pos == pytest.approx(math.log(1.143), abs=1e-4)
    assert d346.contrast_neg == pytest.approx(math.log(1.225), abs=1e-4)
    assert sensor_model("gen4").pixel_pitch_um == 4.86
    for m in SENSOR_MODELS.values():
        assert {"width", "height"} <= set(m.documented) and m.source
        assert set(m.documented) <= set(m.__dataclass_fields__)
        assert 0 < m.contrast_neg < 1 and 0 < m.contrast_pos < 1 and m.refractory_us >= 0


def test_unknown_preset_names_the_known_ones():
    with pytest.raises(ValueError, match="unknown sensor preset 'gen9'.*gen4"):
        sensor_model("gen9")


def test_every_figure_says_where_it_comes_from():
    fields = ("width", "height", "pixel_pitch_um", "contrast_pos", "contrast_neg", "contrast_sigma", "refractory_us")
    for m in SENSOR_MODELS.values():
        for f in fields:
            where = m.source_of(f)
            # a documented field names its document; the others say they are typical values
            assert where.startswith("typical") == (f not in m.documented), (m.name, f, where)
    assert "4.86 um" in sensor_model("gen4").source_of("pixel_pitch_um")
    assert "9 um" in sensor_model("dvxplorer").source_of("pixel_pitch_um")
    assert "2.1 %" in sensor_model("dvs128").source_of("contrast_sigma")
    # the typical thresholds are v2e's / ESIM's 0.2 log step
    for name in ("dvxplorer", "gen3", "gen4"):
        assert sensor_model(name).contrast_pos == sensor_model(name).contrast_neg == 0.2
    with pytest.raises(ValueError, match="no recorded source for 'fx'"):
        sensor_model("gen4").source_of("fx")
