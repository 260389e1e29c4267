"""The analytic fast path: buffer-reusing renders, dirty boxes, span scans, against the plain path."""

import math

import numpy as np
import pytest

from evedge.sim._events import _box_spans, _convert, _scan
from evedge.sim.motion import PlanarMotion
from evedge.sim.planar import Circle, Polygon, ShapesRenderer, StripeLayer, StripesRenderer, star_polygon


def ref_box_spans(boxes, width, height):
    """Pure-Python reference: the union of the boxes as a mask, cut into maximal row-major runs."""
    mask = np.zeros(width * height, dtype=bool)
    for r0, r1, c0, c1 in np.asarray(boxes).reshape(-1, 4):
        for r in range(r0, r1):
            mask[r * width + c0:r * width + c1] = True
    spans, i = [], 0
    while i < mask.size:
        if mask[i]:
            j = i
            while j < mask.size and mask[j]:
                j += 1
            spans.append((i, j))
            i = j
        else:
            i += 1
    return spans


def _random_boxes(rng, n, width, height):
    out = []
    for _ in range(n):
        r0, r1 = sorted(rng.integers(0, height + 1, 2))
        c0, c1 = sorted(rng.integers(0, width + 1, 2))
        out += [r0, r1, c0, c1]
    return np.array(out, dtype=np.int64)


@pytest.mark.parametrize("seed", range(6))
def test_box_spans_match_reference(seed):
    rng = np.random.default_rng(seed)
    width, height = int(rng.integers(1, 30)), int(rng.integers(1, 20))
    nb = int(rng.integers(1, 7))
    boxes = _random_boxes(rng, nb, width, height)
    if seed == 0:
        boxes[:4] = [0, height, 0, width]  # the whole image: one span
    out = np.full(2 * height * nb, -1, dtype=np.int64)
    n = _box_spans(boxes, nb, width, height, out)
    got = [(int(out[2 * k]), int(out[2 * k + 1])) for k in range(n)]
    assert got == ref_box_spans(boxes, width, height)
    if seed == 0:
        assert got == [(0, width * height)]


def test_scan_over_spans_equals_full_scan_when_the_rest_is_unchanged():
    rng = np.random.default_rng(3)
    width, height, eps = 23, 17, 1e-3
    n = width * height
    boxes = _random_boxes(rng, 3, width, height)
    spans_list = ref_box_spans(boxes, width, height)
    inside = np.zeros(n, dtype=bool)
    for a, b in spans_list:
        inside[a:b] = True
    i0 = rng.uniform(0, 1, n)
    i1 = np.where(inside & (rng.random(n) < 0.6), rng.uniform(0, 1, n), i0)
    assert np.any(i1 != i0)
    lref = np.log(i0 + eps) + rng.uniform(-0.1, 0.1, n)
    cpos, cneg = rng.uniform(0.1, 0.3, n), rng.uniform(0.1, 0.3, n)
    e_hi, e_lo = np.exp(lref + cpos), np.exp(lref - cneg)
    spans = np.array(spans_list, dtype=np.int64).ravel()
    cand_s = np.empty(n, dtype=np.int64)
    m, dl = _scan(i0, i1, eps, e_hi, e_lo, spans, len(spans_list), cand_s)
    cand_f = np.empty(n, dtype=np.int64)
    e = np.empty(0)
    full = _convert(i0, i1, 0.0, 1.0, eps, lref, e_hi, e_lo, cpos, cneg, np.full(n, -np.inf), 0.0,
                    np.zeros(n, np.int64), 0.0, np.uint64(1), False, cand_f, 0, np.empty(0, np.int64), e, e,
                    np.empty(0, bool))
    assert (m, dl) == (full[2], full[3])  # bit-identical max |Delta L|
    np.testing.assert_array_equal(cand_s[:m], cand_f[:m])
    assert dl == pytest.approx(np.abs(np.log(i1 + eps) - np.log(i0 + eps)).max(), rel=1e-13)


def _shapes_renderer(width=64, height=48, overlap=False):
    shapes = [Polygon(star_polygon((20, 20), 12, 5, 0.45), 0.1),
              Circle((45.3, 30.2), 9.5, 0.3),
              Polygon(np.array([[-5.0, 40], [10, 35], [4, 60]]), 0.2)]  # crosses the border
    if overlap:
        shapes.append(Circle((26, 22), 6, 0.9))
    motion = PlanarMotion(center_px=(32, 24), velocity_px_s=(40, -25), angular_velocity_rad_s=0.8,
                          amplitude_px=(6, 3), frequency_hz=2.0)
    return ShapesRenderer(width, height, shapes, motion, background=0.7)


def _stripes_renderer():
    layers = [StripeLayer((2, 10), 7.0, 0.0, (30.0, 0.0)), StripeLayer((12, 20), 5.5, math.radians(30), (-20.0, 9.0))]
    return StripesRenderer(32, 22, layers, background=0.4)


@pytest.mark.parametrize("make", [_shapes_renderer, lambda: _shapes_renderer(overlap=True), _stripes_renderer])
def test_intensity_into_reuses_buffers_with_the_same_bytes(make):
    r = make()
    bufs = [np.full(r.width * r.height, np.nan), np.full(r.width * r.height, -3.0)]
    dirty = [None, None]
    times = [0.0, 0.013, 0.5, 0.0131, 1.7, 0.2, 3.0, 0.9]
    for k, t in enumerate(times):
        b = k % 2
        dirty[b] = r.intensity_into(t, bufs[b], dirty[b])
        want = r.intensity(t).ravel()
        assert bufs[b].tobytes() == want.tobytes()
        # outside the boxes: the background, exactly
        outside = np.ones(want.size, dtype=bool)
        for r0, r1, c0, c1 in dirty[b].reshape(-1, 4):
            for y in range(r0, r1):
                outside[y * r.width + c0:y * r.width + c1] = False
        assert np.all(want[outside] == r.background)
        if t < 0.6:  # (later the shapes have left the image)
            assert np.any(want != r.background)


def test_converter_fast_path_equals_plain_renderer():
    """The same events, truth and sample count through ``intensity_into`` and through ``intensity`` only."""
    from evedge.sim import ConverterParams, EventConverter

    class PlainOnly:
        """Hides ``intensity_into``: the converter takes its generic path."""

        def __init__(self, inner):
            self._r = inner
            self.width, self.height = inner.width, inner.height

        def __getattr__(self, name):
            if name == "intensity_into":
                raise AttributeError(name)
            return getattr(self._r, name)

        def intensity(self, t_s):
            return self._r.intensity(t_s)

        def flow(self, t_s):
            return self._r.flow(t_s)

        def edges(self, t_s):
            return self._r.edges(t_s)

        def max_speed_px_s(self, t0_s, t1_s):
            return self._r.max_speed_px_s(t0_s, t1_s)

        def close(self):
            pass

    params = ConverterParams(contrast_sigma=0.03, refractory_us=50.0, noise_rate_hz=2.0, jitter_us=20.0)
    outs = []
    for r in (_shapes_renderer(), PlainOnly(_shapes_renderer())):
        conv = EventConverter(r, params, seed=5, duration_s=0.12)
        parts = [conv.process(t) for t in (0.03, 0.07, 0.12)]
        ev = np.concatenate([p[0] for p in parts])
        tr = np.concatenate([p[1] for p in parts])
        outs.append((ev.tobytes(), tr.tobytes(), conv.n_samples, conv.n_rejected, conv._into))
    assert outs[0][4] and not outs[1][4]
    assert outs[0][:4] == outs[1][:4]
    assert len(outs[0][0]) > 1000


@pytest.mark.parametrize("t", [0.0, 0.37, 1.1])
def test_in_kernel_motion_equals_planar_motion_to_image(t):
    """The kernel moves the shapes as ``PlanarMotion.to_image``: same image as the shapes moved beforehand."""
    r = _shapes_renderer()
    moved = []
    for p in r.polygons:
        x, y = r.motion.to_image(p.vertices_px[:, 0], p.vertices_px[:, 1], t)
        moved.append(Polygon(np.stack([x, y], axis=1), p.intensity))
    for c in r.circles:
        x, y = r.motion.to_image(np.array([c.center_px[0]]), np.array([c.center_px[1]]), t)
        moved.append(Circle((float(x[0]), float(y[0])), c.radius_px, c.intensity))
    static = ShapesRenderer(r.width, r.height, moved, PlanarMotion(), background=r.background)
    assert r.intensity(t).tobytes() == static.intensity(0.0).tobytes()
    assert np.array_equal(r.edges(t), static.edges(0.0))
