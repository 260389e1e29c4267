"""Geometric steps on the shapes lose no event: counts per (pixel, polarity) equal a dense reference.

The default sampling of the analytic shapes scenes takes steps bounded only by
``max_step_px`` and sub-samples the pixels the renderer cannot prove monotone
over a step (``ShapesRenderer.nonmonotone_pixels``). The reference here is the
verified sampling with ``lambda = 0.1`` and steps of at most 0.02 px (a
quarter of the sub-samples' spacing, every pixel sampled), exact times.
"""

import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from evedge.sim import ConverterParams, EventConverter, parse_scene
from evedge.sim.motion import PlanarMotion
from evedge.sim.planar import Circle, Polygon, ShapesRenderer, regular_polygon, star_polygon

SCENES = Path(__file__).resolve().parents[2] / "scenes"
DENSE = dict(sampling="verified", lambda_=0.1, max_step_px=0.02)


def _counts(ev, width, height):
    key = (ev["y"].astype(np.int64) * width + ev["x"]) * 2 + ev["p"].astype(np.int64)
    return np.bincount(key, minlength=2 * width * height)


def _run(renderer, params, duration_s, seed=1):
    conv = EventConverter(renderer, params, seed=seed, duration_s=duration_s)
    ev, _ = conv.process(duration_s)
    return ev, conv


def _compare(make_renderer, params: ConverterParams, duration_s):
    got, conv = _run(make_renderer(), params, duration_s)
    want, _ = _run(make_renderer(), ConverterParams(**{**params.__dict__, **DENSE}), duration_s)
    assert conv.geometric_steps and conv.n_subsampled > 0
    r = conv.renderer
    a, b = _counts(got, r.width, r.height), _counts(want, r.width, r.height)
    assert np.array_equal(a, b), f"{int(np.abs(a - b).sum())} events differ of {want.shape[0]}"
    return got, conv


@pytest.mark.parametrize("name, motion", [
    ("shapes_translation", {"frequency_hz": 2.0, "chirp_hz_s": 0.0}),  # ~290 px/s, turns at 0.125 s
    ("shapes_rotation", {"frequency_hz": 2.0, "chirp_hz_s": 0.0}),
])
def test_scene_counts_equal_dense_reference(name, motion):
    data = copy.deepcopy(tomllib.loads((SCENES / f"{name}.toml").read_text()))
    data["motion"].update(motion)
    scene = parse_scene(data, source=f"{name}.toml")
    got, conv = _compare(scene.build_renderer, scene.params, 0.16)
    assert got.shape[0] > 20000 and conv.n_extremum_splits > 0


def _thin_features():
    sharp_star = Polygon(star_polygon((14.0, 12.0), 7.0, 5, 0.15), 0.1)  # tips a fraction of a pixel wide
    tiny_triangle = Polygon(regular_polygon((30.0, 8.0), 1.2, 3), 0.15)  # smaller than 2 px
    sliver = Polygon(np.array([[26.0, 16.0], [38.0, 17.5], [26.0, 16.6]]), 0.2)  # 0.6 px at its base
    dot = Circle((34.0, 22.0), 0.8, 0.3)
    return [sharp_star, tiny_triangle, sliver, dot]


@pytest.mark.parametrize("motion", [
    PlanarMotion(velocity_px_s=(60.0, -20.0), amplitude_px=(4.0, 3.0), frequency_hz=9.0),  # ~300 px/s, turning
    PlanarMotion(center_px=(20.0, 14.0), angle_amplitude_rad=0.5, frequency_hz=6.0),  # rotation, ~200 px/s
])
def test_thin_fast_features_counts_equal_dense_reference(motion):
    def make():
        return ShapesRenderer(44, 30, _thin_features(), motion, background=0.8)

    params = ConverterParams(contrast_pos=0.15, contrast_neg=0.15, contrast_sigma=0.03, refractory_us=20.0)
    got, conv = _compare(make, params, 0.12)
    assert got.shape[0] > 3000 and conv.n_extremum_splits > 0


def test_thin_bar_crossing_a_pixel_within_one_step():
    """A 0.3 px bar crosses a pixel within one 2 px step: its pixels are sub-sampled, the events those of dense steps."""
    bar = Polygon(np.array([[-3.0, -20.0], [-2.7, -20.0], [-2.7, 20.0], [-3.0, 20.0]]), 0.1)
    r = ShapesRenderer(8, 3, [bar], PlanarMotion(velocity_px_s=(100.0, 0.0)), background=0.8)
    dense = ConverterParams(contrast_pos=0.1, contrast_neg=0.1, lambda_=0.1)
    geo = ConverterParams(contrast_pos=0.1, contrast_neg=0.1, sampling="geometric", max_step_px=2.0)
    want, _ = _run(r, dense, 0.1, seed=0)
    got, conv = _run(r, geo, 0.1, seed=0)
    assert want.shape[0] > 50 and conv.n_subsampled > 0 and conv.n_rejected == 0
    assert got.tobytes() == want.tobytes()


@pytest.mark.parametrize("motion", [
    PlanarMotion(amplitude_px=(22.0, 7.0), frequency_hz=2.0),
    PlanarMotion(center_px=(20.0, 14.0), angular_velocity_rad_s=3.0, velocity_px_s=(30.0, 10.0)),
])
def test_nonmonotone_pixels_hold_every_non_monotone_pixel(motion):
    """Slow reference: every pixel whose intensity, sampled 400 times over a step, is not monotone is named."""
    shapes = _thin_features() + [Polygon(regular_polygon((10.0, 24.0), 4.0, 4, math.pi / 5), 0.3),
                                 Circle((22.0, 22.0), 5.0, 0.2)]
    r = ShapesRenderer(44, 30, shapes, motion, background=0.8)
    npix = r.width * r.height
    pix = np.arange(npix, dtype=np.int64)
    n_found = 0
    for t0 in (0.0, 0.05, 0.124, 0.2):  # 0.125 s: a turn of the first motion
        t1 = t0 + 2e-3
        vmax = r.max_speed_px_s(t0, t1)
        named = np.zeros(npix, dtype=bool)
        named[r.nonmonotone_pixels(t0, t1, 0.7072 + vmax * (t1 - t0))] = True
        ts = np.linspace(t0, t1, 401)
        vals = np.stack([r.pixel_intensity(pix, np.full(npix, t)) for t in ts])
        d = np.diff(vals, axis=0)
        up = (d > 1e-12).any(axis=0)
        down = (d < -1e-12).any(axis=0)
        non_monotone = up & down
        n_found += int(non_monotone.sum())
        assert not np.any(non_monotone & ~named), np.flatnonzero(non_monotone & ~named)
        assert named.sum() < 0.5 * npix  # and it is selective
    assert n_found > 10
