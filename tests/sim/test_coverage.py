"""Exact area coverage and edge maps of the analytic renderers against slow references."""

import math

import numpy as np
import pytest

from evedge.sim import coverage
from evedge.sim.motion import PlanarMotion
from evedge.sim.planar import Circle, Polygon, ShapesRenderer, StripeLayer, StripesRenderer, star_polygon


def _random_polygon(rng, n, cx, cy, r):
    """A random star-shaped (possibly concave) simple polygon around (cx, cy)."""
    ang = np.sort(rng.uniform(0, 2 * np.pi, n))
    rad = r * rng.uniform(0.3, 1.0, n)
    return cx + rad * np.cos(ang), cy + rad * np.sin(ang)


def test_polygon_pixel_area_matches_quadrature(ref):
    rng = np.random.default_rng(0)
    for trial in range(40):
        vx, vy = _random_polygon(rng, int(rng.integers(3, 9)), rng.uniform(-1, 1), rng.uniform(-1, 1), 1.5)
        x0, y0 = rng.uniform(-1.5, 0.5, 2)
        got = coverage.polygon_box_area(vx, vy, (x0, y0, x0 + 1, y0 + 1))
        want = ref.ref_polygon_box_area(vx, vy, x0, y0, x0 + 1, y0 + 1)
        assert got == pytest.approx(want, abs=1e-9), trial


def test_disk_pixel_area_matches_quadrature(ref):
    rng = np.random.default_rng(1)
    for trial in range(60):
        cx, cy = rng.uniform(-1.5, 1.5, 2)
        r = rng.uniform(0.1, 2.0)
        got = coverage.disk_box_area(cx, cy, r, (-0.5, -0.5, 0.5, 0.5))
        want = ref.ref_disk_box_area(cx, cy, r, -0.5, -0.5, 0.5, 0.5)
        assert got == pytest.approx(want, abs=1e-9), trial


def test_stripe_fraction_matches_quadrature(ref):
    rng = np.random.default_rng(2)
    for trial in range(40):
        a = rng.uniform(0, 2 * np.pi) if trial % 4 else 0.0
        nx, ny = math.cos(a), math.sin(a)
        period = rng.uniform(1.5, 10)
        duty = rng.uniform(0.2, 0.8)
        offset = rng.uniform(-20, 20)
        x, y = int(rng.integers(0, 10)), int(rng.integers(0, 10))
        got = coverage.stripe_dark_fraction(x, y, nx, ny, offset, period, duty)
        want = ref.ref_stripe_dark_fraction(x, y, nx, ny, offset, period, duty)
        assert got == pytest.approx(want, abs=1e-9), trial


def test_rendered_polygon_and_disk_integrate_to_their_areas():
    # a star (concave) and a disk fully inside the image: coverage sums to the exact area
    star = star_polygon((20.3, 15.7), 9.0, 5, 0.45, 0.1)
    x, y = star[:, 0], star[:, 1]
    area = 0.5 * abs(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    r = ShapesRenderer(48, 40, [Polygon(star, 0.0), Circle((34.2, 27.9), 6.3, 0.0)], PlanarMotion(), background=1.0)
    img = r.intensity(0.0)
    assert np.sum(1.0 - img) == pytest.approx(area + np.pi * 6.3**2, abs=1e-8)


def test_shape_pixels_match_reference_coverage(ref):
    rng = np.random.default_rng(3)
    vx, vy = _random_polygon(rng, 7, 10.2, 9.6, 6.0)
    r = ShapesRenderer(20, 20, [Polygon(np.stack([vx, vy], 1), 0.0)], PlanarMotion(), background=1.0)
    img = r.intensity(0.0)
    for yy in range(20):
        for xx in range(20):
            want = ref.ref_polygon_box_area(vx, vy, xx - 0.5, yy - 0.5, xx + 0.5, yy + 0.5)
            assert 1.0 - img[yy, xx] == pytest.approx(want, abs=1e-9), (xx, yy)


def test_edge_map_definition_on_axis_aligned_square():
    # square boundaries on pixel borders (half-integers): no pixel is crossed, no edge
    sq = np.array([[2.5, 2.5], [7.5, 2.5], [7.5, 7.5], [2.5, 7.5]])
    r = ShapesRenderer(10, 10, [Polygon(sq, 0.1)], PlanarMotion(), background=0.9)
    assert not r.edges(0.0).any()
    img = r.intensity(0.0)
    assert np.all(img[3:8, 3:8] == pytest.approx(0.1)) and img[2, 2] == pytest.approx(0.9)
    # shifted by 0.3 px: exactly the ring of pixels its boundary passes through
    r = ShapesRenderer(10, 10, [Polygon(sq + 0.3, 0.1)], PlanarMotion(), background=0.9)
    e = r.edges(0.0)
    want = np.zeros((10, 10), bool)
    want[3:9, 3] = want[3:9, 8] = want[3, 3:9] = want[8, 3:9] = True
    np.testing.assert_array_equal(e, want)


def test_stripes_edges_and_two_bands():
    layers = [StripeLayer((0, 4), 8.0, 0.0, (10.0, 0.0)), StripeLayer((4, 8), 8.0, 0.0, (30.0, 0.0), phase_px=0.25)]
    r = StripesRenderer(16, 8, layers)
    e = r.edges(0.0)
    # top band: boundaries at x = 0, 4, 8, 12 (pixel centres): edge pixels at those columns
    assert set(np.flatnonzero(e[0])) == {0, 4, 8, 12}
    # bottom band: boundaries at 0.25 + 4k, also inside the squares of columns 0, 4, 8, 12
    assert set(np.flatnonzero(e[5])) == {0, 4, 8, 12}
    img = r.intensity(0.0)
    assert img[0, 0] == pytest.approx(0.5) and img[5, 0] == pytest.approx(0.8 - 0.6 * 0.25)
    np.testing.assert_array_equal(r.flow(0.0)[0, :4], 10.0)
    np.testing.assert_array_equal(r.flow(0.0)[0, 4:], 30.0)


def test_public_coverage_functions_validate():
    with pytest.raises(ValueError, match="vx"):
        coverage.polygon_box_area([0, 1], [0, 1], (0, 0, 1, 1))
    with pytest.raises(ValueError, match="box"):
        coverage.disk_box_area(0, 0, 1, (1, 0, 0, 1))
    with pytest.raises(ValueError, match="radius_px"):
        coverage.disk_box_area(0, 0, -1, (0, 0, 1, 1))
    with pytest.raises(ValueError, match="period_px"):
        coverage.stripe_dark_fraction(0, 0, 1, 0, 0, 0, 0.5)


def test_polygons_crossing_the_image_border_match_reference(ref):
    # the row rasteriser folds area left of the image into column 0 and drops what lies right of it
    rng = np.random.default_rng(7)
    for trial in range(6):
        vx, vy = _random_polygon(rng, int(rng.integers(3, 11)), rng.uniform(-3, 15), rng.uniform(-3, 12), 7.0)
        r = ShapesRenderer(12, 9, [Polygon(np.stack([vx, vy], 1), 0.0)], PlanarMotion(), background=1.0)
        img = r.intensity(0.0)
        edges = r.edges(0.0)
        for yy in range(9):
            for xx in range(12):
                want = ref.ref_polygon_box_area(vx, vy, xx - 0.5, yy - 0.5, xx + 0.5, yy + 0.5)
                assert 1.0 - img[yy, xx] == pytest.approx(want, abs=1e-9), (trial, xx, yy)
                assert edges[yy, xx] == (1e-9 < want < 1 - 1e-9) or min(want, 1 - want) < 1e-8


def test_rendered_disks_match_reference(ref):
    rng = np.random.default_rng(9)
    for trial in range(3):
        cx, cy, r = rng.uniform(-2, 12), rng.uniform(-2, 10), rng.uniform(1.0, 6.0)
        img = ShapesRenderer(10, 8, [Circle((cx, cy), r, 0.0)], PlanarMotion(), background=1.0).intensity(0.0)
        for yy in range(8):
            for xx in range(10):
                want = ref.ref_disk_box_area(cx, cy, r, xx - 0.5, yy - 0.5, xx + 0.5, yy + 0.5)
                assert 1.0 - img[yy, xx] == pytest.approx(want, abs=1e-9), (trial, xx, yy)


def test_nearest_normal_kernel_matches_reference():
    from evedge.sim._nearest import _nearest_outward_normal

    rng = np.random.default_rng(11)
    sq = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [0.0, 4.0]])  # orientation +1 (shoelace > 0)
    tri = np.array([[10.0, 0.0], [12.0, 5.0], [8.0, 5.0]])
    px = np.concatenate([sq[:, 0], tri[:, 0]])
    py = np.concatenate([sq[:, 1], tri[:, 1]])
    starts = np.array([0, 4, 7])
    orient = np.array([1.0, 1.0])
    flip = np.array([1.0, -1.0])
    q = rng.uniform(-3, 15, (200, 2))
    nx, ny = np.empty(200), np.empty(200)
    _nearest_outward_normal(q[:, 0].copy(), q[:, 1].copy(), px, py, starts, orient, flip,
                            np.array([5.0]), np.array([12.0]), np.array([2.0]), np.array([1.0]), nx, ny)

    def seg_dist(p, a, b):
        t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0, 1)
        return np.linalg.norm(a + t * (b - a) - p)

    for i, p in enumerate(q):
        best = (np.inf, None)
        for poly, f in ((sq, 1.0), (tri, -1.0)):
            for k in range(len(poly)):
                a, b = poly[k - 1], poly[k]
                d = seg_dist(p, a, b)
                if d < best[0]:
                    e = (b - a) / np.linalg.norm(b - a)
                    best = (d, f * np.array([e[1], -e[0]]))
        dc = np.linalg.norm(p - [5.0, 12.0])
        if abs(dc - 2.0) < best[0]:
            best = (abs(dc - 2.0), (p - [5.0, 12.0]) / dc)
        np.testing.assert_allclose([nx[i], ny[i]], best[1], atol=1e-12)


@pytest.mark.parametrize("angle_deg", [0.0, 90.0, 33.0, 200.0])
def test_rendered_stripes_match_reference(ref, angle_deg):
    # covers the kernel's fast paths (whole pixel inside one stripe) and the row copy (angle 0)
    a = math.radians(angle_deg)
    layer = StripeLayer((1, 7), 5.3, a, (40.0, -10.0), dark=0.1, light=0.9, duty=0.4, phase_px=0.7)
    r = StripesRenderer(11, 8, [layer], background=0.5)
    t = 0.013
    img = r.intensity(t)
    nx, ny = layer.normal
    offset = nx * 40.0 * t + ny * -10.0 * t + 0.7
    assert np.all(img[0] == 0.5) and np.all(img[7] == 0.5)
    for yy in range(1, 7):
        for xx in range(11):
            f = ref.ref_stripe_dark_fraction(xx, yy, nx, ny, offset, 5.3, 0.4)
            assert img[yy, xx] == pytest.approx(0.9 + f * (0.1 - 0.9), abs=1e-9), (xx, yy)
