"""Exact crossing times on analytic scenes, against an independent closed form.

A straight vertical edge moving at constant speed ``v`` over pixel ``x`` leaves
the dark side on a fraction ``f(t) = clamp(a + b t, 0, 1)`` of the pixel
square (``a``, ``b`` from the edge position), so ``I(t) = light + f (dark -
light)`` and each level ``L0 + k C`` of ``log(I + eps)`` is crossed at a time
solved in closed form. Nothing of the simulator's kernels is used here.
"""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from evedge.sim import EventConverter, parse_scene, simulate

sys.path.insert(0, str(Path(__file__).parent))
from _renderers import StillRenderer  # noqa: E402

EPS = 1e-3
C = 0.2
DARK, LIGHT = 0.2, 0.8




def _levels(start, end):
    """Levels ``start + k C`` (k >= 1) crossed going from log intensity ``start`` to ``end``."""
    step = C if end > start else -C
    out = []
    k = 1
    while (start + k * step <= end) if step > 0 else (start + k * step >= end):
        out.append(start + k * step)
        k += 1
    return out


def _want_times(width, edge0, speed, dark_right):
    """Closed-form crossing times per pixel for an edge at ``edge0 + speed t`` (pixel centre x, square [x-0.5, x+0.5]).

    ``dark_right``: the dark side is right of the edge (covered fraction
    ``clamp(x + 0.5 - e(t), 0, 1)``), else left (``clamp(e(t) - x + 0.5, 0, 1)``).
    """
    want = {}
    for x in range(width):
        def frac(t):
            e = edge0 + speed * t
            return min(1.0, max(0.0, (x + 0.5 - e) if dark_right else (e - x + 0.5)))

        f0 = frac(0.0)
        f_end = frac(1e3)  # long after: the edge has passed
        l0 = math.log(LIGHT + f0 * (DARK - LIGHT) + EPS)
        l_end = math.log(LIGHT + f_end * (DARK - LIGHT) + EPS)
        times = []
        for lv in _levels(l0, l_end):
            f = (math.exp(lv) - EPS - LIGHT) / (DARK - LIGHT)
            # e(t) = x + 0.5 - f (dark right) or x - 0.5 + f (dark left)
            e = (x + 0.5 - f) if dark_right else (x - 0.5 + f)
            times.append((e - edge0) / speed)
        want[x] = (times, l_end > l0)
    return want


def _stripes(width, speed, crossing_times="auto"):
    # u = x - v t - phase, dark where u mod 400 < 200: the edge u = 0 sits at e(t) = phase + v t with dark
    # on its right; the other edges are far outside the sensor
    d = {
        "scene": {"kind": "stripes", "duration_s": (width + 4) / speed, "seed": 0, "frame_rate_hz": 0},
        "sensor": {"width": width, "height": 3},
        "events": {"contrast_pos": C, "contrast_neg": C, "crossing_times": crossing_times},
        "stripes": [{"period_px": 400.0, "velocity_px_s": [speed, 0.0], "dark": DARK, "light": LIGHT,
                     "phase_px": -2.5}],
    }
    return parse_scene(d, "edge.toml"), dict(edge0=-2.5, speed=speed, dark_right=True)


def _square(width, speed, crossing_times="auto"):
    # a dark square whose left edge starts right of the sensor and moves left: pixels get covered (OFF)
    x0 = width + 1.5
    d = {
        "scene": {"kind": "shapes", "duration_s": (width + 4) / speed, "seed": 0, "frame_rate_hz": 0,
                  "background": LIGHT},
        "sensor": {"width": width, "height": 3},
        "events": {"contrast_pos": C, "contrast_neg": C, "crossing_times": crossing_times},
        "motion": {"velocity_px_s": [-speed, 0.0]},
        "shapes": [{"kind": "polygon", "intensity": DARK,
                    "vertices_px": [[x0, -50.0], [x0 + 500.0, -50.0], [x0 + 500.0, 60.0], [x0, 60.0]]}],
    }
    return parse_scene(d, "square.toml"), dict(edge0=x0, speed=-speed, dark_right=True)


def _errors_us(scene, edge):
    rec = simulate(scene, progress=False)
    ev, tr = rec.events, rec.truth
    assert np.all(tr["is_signal"])
    want = _want_times(scene.sensor.width, **edge)
    dt = []
    for x in range(scene.sensor.width):
        times, up = want[x]
        for y in range(scene.sensor.height):
            sel = (ev["x"] == x) & (ev["y"] == y)
            got = np.sort(tr["t_ns"][sel]) / 1e3
            assert got.shape[0] == len(times), (x, y)
            assert np.all(ev["p"][sel] == up)
            dt.append(got - np.array(times) * 1e6)
            # the tonic-compatible us column is the same instant, rounded
            assert np.all(np.abs(np.sort(ev["t"][sel]) - got) <= 0.5 + 1e-6)
    return np.abs(np.concatenate(dt))


@pytest.mark.parametrize("speed", [100.0, 1000.0])
@pytest.mark.parametrize("make", [_stripes, _square])
def test_exact_times_match_closed_form(make, speed):
    width = 12 if speed < 500 else 30
    scene, edge = make(width, speed)
    err = _errors_us(scene, edge)
    assert err.size >= width * 3 * 6
    assert np.median(err) <= 0.05 and np.percentile(err, 95) <= 0.2, (np.median(err), np.percentile(err, 95))
    # ns output: the rounding of t_ns is the floor of what can be checked
    assert err.max() < 0.01
    # the linear interpolation it replaces is measurably worse (the issue measured 4.95 us at 100 px/s)
    lin = _errors_us(*make(width, speed, "linear"))
    assert np.median(lin) > 20 * max(np.median(err), 1e-3)


def test_exact_refuses_a_renderer_without_pixel_intensity():
    from evedge.sim import ConverterParams

    class Flat(StillRenderer):
        width = height = 2

    with pytest.raises(ValueError, match="crossing_times='exact' needs a renderer with pixel_intensity"):
        EventConverter(Flat(), ConverterParams(crossing_times="exact"), seed=0, duration_s=0.1)
    with pytest.raises(ValueError, match="crossing_times must be one of"):
        ConverterParams(crossing_times="cubic")


@pytest.mark.parametrize("name", ["stripes", "shapes_translation", "shapes_rotation"])
def test_pixel_intensity_is_the_rendered_image(name):
    from pathlib import Path

    from evedge.sim import load_scene

    r = load_scene(Path(__file__).resolve().parents[2] / "scenes" / f"{name}.toml").build_renderer()
    for t in (0.0, 0.137, 1.71):
        img = r.intensity(t).ravel()
        got = r.pixel_intensity(np.arange(img.size, dtype=np.int64), np.full(img.size, t))
        # stripes: the renderer's arithmetic to the bit; polygons: clipping vs row accumulation
        np.testing.assert_allclose(got, img, rtol=0, atol=0 if name == "stripes" else 1e-11)


def test_geometric_sampling_same_events_on_stripes_with_fewer_samples(stripes_dict):
    d = stripes_dict(width=24, height=6, duration_s=0.1, velocity_px_s=[150.0, 40.0], angle_deg=20.0)
    d["events"]["sampling"] = "verified"
    ver = simulate(parse_scene(d, "v.toml"), progress=False, frame_rate_hz=0)
    d["events"]["sampling"] = "geometric"
    geo = simulate(parse_scene(d, "g.toml"), progress=False, frame_rate_hz=0)
    # "auto" picks geometric steps for stripes: their pixels are monotone over a 0.5 px step
    d["events"]["sampling"] = "auto"
    auto = simulate(parse_scene(d, "a.toml"), progress=False, frame_rate_hz=0)
    assert auto.events.tobytes() == geo.events.tobytes()
    d["events"]["max_step_px"] = 5.0  # beyond the stripes' monotone displacement: verified steps
    assert simulate(parse_scene(d, "a.toml"), progress=False, frame_rate_hz=0).metadata["n_samples"] > \
        geo.metadata["n_samples"]
    d["events"].update(sampling="geometric", max_step_px=0.5)
    assert geo.metadata["n_samples"] < ver.metadata["n_samples"] / 2
    # the same events; times within 1 ns (so a time on a half microsecond may round to the other us)
    a, b = (np.lexsort((r.truth["t_ns"], r.events["p"], r.events["x"], r.events["y"])) for r in (geo, ver))
    assert geo.events.shape == ver.events.shape
    np.testing.assert_array_equal(geo.events[["x", "y", "p"]][a], ver.events[["x", "y", "p"]][b])
    assert np.abs(geo.truth["t_ns"][a] - ver.truth["t_ns"][b]).max() <= 1
    d["events"]["crossing_times"] = "linear"
    with pytest.raises(ValueError, match="sampling='geometric' needs exact crossing times"):
        simulate(parse_scene(d, "g.toml"), progress=False, frame_rate_hz=0)


def test_geometric_sampling_splits_a_stripes_step_hiding_an_excursion(stripes_dict):
    """Stripes 0.6 px wide under 2 px steps (beyond their monotone step): the midpoint check halves steps."""
    d = stripes_dict(width=16, height=2, duration_s=0.05, velocity_px_s=[100.0, 0.0], period_px=3.0, duty=0.2)
    d["events"].update(contrast_pos=0.1, contrast_neg=0.1, sampling="geometric", max_step_px=2.0)
    geo = simulate(parse_scene(d, "g.toml"), progress=False, frame_rate_hz=0)
    d["events"].update(sampling="verified", max_step_px=0.02, **{"lambda": 0.1})
    dense = simulate(parse_scene(d, "v.toml"), progress=False, frame_rate_hz=0)
    assert geo.metadata["n_rejected_steps"] > 0 and dense.events.shape[0] > 100
    # the midpoint check (the fallback for renderers without nonmonotone_pixels) still misses excursions
    # shorter than half a step: most events, not all (the shapes' sub-sampling is complete: test_completeness)
    assert 0.95 * dense.events.shape[0] <= geo.events.shape[0] <= dense.events.shape[0]


def test_crossing_levels_kernel_matches_reference(ref):
    """The crossings of :func:`_crossing_levels` are the reference's without refractory and jitter."""
    from evedge.sim._exact import _crossing_levels

    rng = np.random.default_rng(7)
    n = 400
    i0 = rng.uniform(0, 1, n)
    i1 = np.where(rng.random(n) < 0.3, i0, rng.uniform(0, 1, n))
    eps = 1e-3
    cpos, cneg = rng.uniform(0.05, 0.4, n), rng.uniform(0.05, 0.4, n)
    l0 = np.log(i0 + eps)
    lref = np.clip(l0 - rng.uniform(-0.99, 0.99, n) * cpos, l0 - 0.99 * cpos, l0 + 0.99 * cneg)
    want, wl, _, _ = ref.ref_convert(i0, i1, 1.0, 1.01, eps, lref, cpos, cneg, np.full(n, -np.inf), 0.0,
                                     np.zeros(n, np.int64), 0.0, np.uint64(0))
    state = [lref.copy(), np.exp(lref + cpos), np.exp(lref - cneg)]
    cand = np.arange(n, dtype=np.int64)
    e = np.empty(0)
    m, moved = _crossing_levels(i0, i1, 1.0, 1.01, eps, *state, cpos, cneg, False, cand, n, np.empty(0, np.int64),
                                e, e, np.empty(0, bool))
    assert m == len(want) > 50
    pix, level, t, pol = np.empty(m, np.int64), np.empty(m), np.empty(m), np.empty(m, bool)
    _crossing_levels(i0, i1, 1.0, 1.01, eps, *state, cpos, cneg, True, cand, n, pix, level, t, pol)
    np.testing.assert_array_equal(pix, [w[0] for w in want])
    np.testing.assert_allclose(t, [w[1] for w in want], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(pol, [w[3] for w in want])
    np.testing.assert_allclose(state[0], wl, rtol=0, atol=1e-12)
    # each crossing's level is the reference level it crossed: L interpolated at its time
    np.testing.assert_allclose(level, l0[pix] + (np.log(i1[pix] + eps) - l0[pix]) * (t - 1.0) / 0.01, atol=1e-9)


def test_stripes_monotone_step():
    from evedge.sim.planar import StripeLayer, StripesRenderer

    r = StripesRenderer(10, 4, [StripeLayer((0, 2), 12.0, 0.0, (5.0, 0.0)),
                                StripeLayer((2, 4), 10.0, math.radians(45), (5.0, 0.0), duty=0.2)])
    assert r.monotone_step_px == pytest.approx(2.0 - math.sqrt(2))  # the 2 px stripes of the 45 deg layer


def test_polygon_pixel_coverage_matches_clipping():
    """The one-pass per-pixel coverage against Sutherland-Hodgman clipping (itself checked against a
    pure-Python reference in test_coverage.py), on convex and star polygons of both orientations."""
    from evedge.sim._coverage import _polygon_box_area
    from evedge.sim._exact import _polygon_pixel_coverage
    from evedge.sim.planar import regular_polygon, star_polygon

    rng = np.random.default_rng(0)
    partial = 0
    for trial in range(60):
        centre = (rng.uniform(4, 8), rng.uniform(4, 8))
        if trial % 2:
            v = star_polygon(centre, rng.uniform(1, 5), 5, 0.45, rng.uniform(0, 6))
        else:
            v = regular_polygon(centre, rng.uniform(0.6, 5), int(rng.integers(3, 8)), rng.uniform(0, 6))
        if trial % 3 == 0:
            v = v[::-1]
        vx, vy = np.ascontiguousarray(v[:, 0]), np.ascontiguousarray(v[:, 1])
        bufs = [np.empty(6 * len(vx) + 16) for _ in range(4)]
        for x in range(13):
            for y in range(13):
                want = min(1.0, _polygon_box_area(vx, vy, len(vx), x - 0.5, y - 0.5, x + 0.5, y + 0.5, *bufs))
                got = _polygon_pixel_coverage(vx, vy, len(vx), x, y)
                assert abs(got - want) < 1e-13, (trial, x, y, got, want)
                partial += 0 < want < 1
    assert partial > 1000
