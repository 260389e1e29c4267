"""Sensor effects (v2e's pixel model) against analytic expectations: low-pass, leak, shot noise, resetting noise."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from evedge.sim import ConverterParams, EventConverter, frames_from_arrays, simulate_frames
from evedge.sim.converter import SENSOR_EFFECT_PRESETS
from evedge.sim.planar import StripeLayer, StripesRenderer

EPS = 1e-3

sys.path.insert(0, str(Path(__file__).parent))
from _renderers import RampRenderer  # noqa: E402  (one pixel, exact log ramp)


def _static(values, duration_s, rate_hz=100.0):
    n = int(round(duration_s * rate_hz)) + 1
    return frames_from_arrays(np.repeat(np.asarray(values, float)[None], n, 0), np.arange(n) / rate_hz)


def test_lowpass_step_response():
    """A step at t = 0: L_lp(t) = L1 + (L0 - L1) exp(-t / tau(I1)), tau = 1 / (2 pi f (I1 + 20/255) / (1 + 20/255))."""
    rate, f, c = 20000.0, 100.0, 0.2
    i0 = np.array([[0.1, 0.8]])
    i1 = np.array([[0.8, 0.1]])  # pixel 0 up (ON), pixel 1 down (OFF, darker: slower)
    n = 400
    frames = np.concatenate([i0[None], np.repeat(i1[None], n - 1, 0)])
    rec = simulate_frames(frames_from_arrays(frames, np.arange(n) / rate),
                          ConverterParams(contrast_pos=c, contrast_neg=c, lowpass_cutoff_hz=f), progress=False)
    for x in (0, 1):
        a, b = math.log(i0[0, x] + EPS), math.log(i1[0, x] + EPS)
        tau = 1.0 / (2 * math.pi * f * (i1[0, x] + 20 / 255) / (1 + 20 / 255))
        m = np.arange(1, int(abs(b - a) / c + 1e-9) + 1)
        want = -tau * np.log(1 - m * c / abs(b - a))
        want = want[want < (n - 1) / rate - 1e-4]  # those inside the frames (less a margin)
        assert want.shape[0] >= 6
        sel = rec.events["x"] == x
        got = np.sort(rec.truth["t_ns"][sel]) * 1e-9
        assert got.shape == want.shape and np.all(rec.events["p"][sel] == (b > a))
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-6)  # 1 us: chords of 50 us samples
    # without the low-pass the same step fires every event at the first frame
    fast = simulate_frames(frames_from_arrays(frames, np.arange(n) / rate), ConverterParams(), progress=False)
    assert fast.events["t"].max() <= 50


def test_leak_events_at_the_leak_rate():
    """A static pixel's reference drifts by r C per second: ON events at k / r."""
    p = ConverterParams(contrast_pos=0.2, leak_rate_hz=5.0)
    rec = simulate_frames(_static(np.full((3, 4), 0.5), 2.0), p, progress=False)
    assert np.all(rec.events["p"]) and np.all(rec.truth["is_signal"])
    for x in range(4):
        sel = (rec.events["x"] == x) & (rec.events["y"] == 1)
        t = np.sort(rec.truth["t_ns"][sel]) * 1e-9
        assert t.shape[0] in (9, 10)
        np.testing.assert_allclose(t, 0.2 * np.arange(1, t.shape[0] + 1), rtol=0, atol=1e-6)
    # per-pixel spread: r_i = r max(0, 1 + sigma N(0, 1)); a pixel's first event is at 1 / r_i
    p = ConverterParams(contrast_pos=0.2, leak_rate_hz=5.0, leak_rate_sigma=0.2)
    rec = simulate_frames(_static(np.full((20, 30), 0.5), 1.0), p, seed=3, progress=False)
    first = {}
    for x, y, t in zip(rec.events["x"], rec.events["y"], rec.truth["t_ns"]):
        first.setdefault((int(x), int(y)), t * 1e-9)
    r = 1.0 / np.array(list(first.values()))
    assert len(r) > 550
    assert abs(r.mean() / 5.0 - 1) < 0.03 and 0.16 < r.std() / 5.0 < 0.24


def test_shot_noise_rate_depends_on_intensity():
    """Poisson at R(I) = rate (1 - 0.75 I): 4x fewer on bright pixels; ON and OFF equally likely."""
    img = np.zeros((20, 40))
    img[:, 20:] = 1.0
    p = ConverterParams(shot_noise_rate_hz=20.0)
    rec = simulate_frames(_static(img, 2.0), p, seed=1, progress=False)
    noise = ~rec.truth["is_signal"]
    assert noise.all()  # static: every event is shot noise
    dark = np.count_nonzero(rec.events["x"] < 20)
    bright = np.count_nonzero(rec.events["x"] >= 20)
    for got, want in ((dark, 20.0 * 2 * 400), (bright, 5.0 * 2 * 400)):
        assert abs(got - want) < 4 * math.sqrt(want), (got, want)
    on = np.count_nonzero(rec.events["p"])
    assert abs(on - rec.events.shape[0] / 2) < 4 * math.sqrt(rec.events.shape[0] / 4)


@pytest.mark.parametrize("refractory_us", [0.0, 5000.0])
def test_resetting_noise_and_refractory(refractory_us):
    """L = L0 + k t: after any emitted event (signal or noise) the next signal event is C / k later."""
    k, c = 10.0, 0.2
    p = ConverterParams(contrast_pos=c, contrast_neg=c, noise_rate_hz=30.0, noise_resets=True,
                        refractory_us=refractory_us)
    conv = EventConverter(RampRenderer(math.log(0.05), k, EPS), p, seed=2, duration_s=2.0)
    ev, tr = conv.process(2.0)
    t = tr["t_ns"] * 1e-9
    noise = ~tr["is_signal"]
    assert 35 < noise.sum() < 90  # 30 Hz for 2 s, less what refractory drops
    gaps = np.diff(t)
    sig_gap = gaps[~noise[1:]]
    np.testing.assert_allclose(sig_gap, c / k, rtol=0, atol=1e-6)
    assert gaps.min() >= refractory_us * 1e-6 - 1e-9
    # the same without resets: signal events on the fixed 20 ms grid, noise independent of them
    q = ConverterParams(contrast_pos=c, contrast_neg=c, noise_rate_hz=30.0, refractory_us=refractory_us)
    ev2, tr2 = EventConverter(RampRenderer(math.log(0.05), k, EPS), q, seed=2, duration_s=2.0).process(2.0)
    sig = tr2["t_ns"][tr2["is_signal"]] * 1e-9
    np.testing.assert_allclose(np.diff(sig), c / k, rtol=0, atol=1e-6)


def test_effects_off_by_default_and_preset_documented():
    p = ConverterParams()
    assert (p.lowpass_cutoff_hz, p.leak_rate_hz, p.shot_noise_rate_hz, p.noise_resets) == (0.0, 0.0, 0.0, False)
    realistic = ConverterParams(**SENSOR_EFFECT_PRESETS["v2e_noisy"])
    assert realistic.lowpass_cutoff_hz > 0 and realistic.leak_rate_hz > 0 and realistic.shot_noise_rate_hz > 0
    rec = simulate_frames(_static(np.full((6, 8), 0.4), 0.5), realistic, seed=0, progress=False)
    assert rec.events.shape[0] > 0
    with pytest.raises(ValueError, match="noise_resets must be True or False"):
        ConverterParams(noise_resets=1)
    with pytest.raises(ValueError, match="not available with the sensor effects"):
        EventConverter(StripesRenderer(8, 4, [StripeLayer((0, 4), 6.0, 0.0, (50.0, 0.0))]),
                       ConverterParams(crossing_times="exact", leak_rate_hz=1.0), seed=0, duration_s=0.1)


@pytest.mark.parametrize("chunk_s", [0.0071, 0.03])
def test_effects_on_a_scene_are_deterministic_and_chunk_independent(stripes_dict, chunk_s):
    from evedge.sim import SceneError, parse_scene, simulate

    d = stripes_dict(width=20, height=10, duration_s=0.06, velocity_px_s=[150.0, 0.0])
    d["events"] = {"effects": "v2e_noisy", "noise_rate_hz": 20.0, "refractory_us": 300.0, "leak_rate_hz": 3.0}
    scene = parse_scene(d, "fx.toml")
    assert scene.params.lowpass_cutoff_hz == 30.0 and scene.params.leak_rate_hz == 3.0
    one = simulate(scene, progress=False, chunk_s=10.0, frame_rate_hz=0)
    many = simulate(scene, progress=False, chunk_s=chunk_s, frame_rate_hz=0)
    assert one.events.tobytes() == many.events.tobytes() and one.truth.tobytes() == many.truth.tobytes()
    assert one.events.shape[0] > 100 and (~one.truth["is_signal"]).sum() > 0
    d["events"] = {"effects": "v2e_loud"}
    with pytest.raises(SceneError, match="key 'events.effects': unknown effects preset 'v2e_loud'"):
        parse_scene(d, "fx.toml")
    d["events"] = {"noise_resets": 1}
    with pytest.raises(SceneError, match="key 'events.noise_resets': expected true or false"):
        parse_scene(d, "fx.toml")


def ref_sensor_interval(l0, l1, t0, t1, lref, cpos, cneg, last_t, refractory_s, noise):
    """:func:`_sensor_interval` in plain Python: per pixel, segments cut at its noise arrivals.

    ``noise``: list of (pixel, time, polarity). Returns the events (pixel, t, polarity, is_noise)
    and the new (lref, last_t). No jitter.
    """
    lref, last_t = list(lref), list(last_t)
    out = []
    for i in range(len(l0)):
        arrivals = sorted((t, p) for (j, t, p) in noise if j == i) + [(None, None)]
        ta, la = t0, l0[i]
        for tn, pn in arrivals:
            tb = t1 if tn is None else tn
            lb = l1[i] if tn is None else l0[i] + (l1[i] - l0[i]) * (tb - t0) / (t1 - t0)
            for sign, c in ((1, cpos[i]), (-1, cneg[i])):
                while sign * (lb - lref[i]) >= c:
                    lref[i] += sign * c
                    tc = ta + (lref[i] - la) / (lb - la) * (tb - ta)
                    if tc - last_t[i] >= refractory_s:
                        out.append((i, tc, sign > 0, False))
                        last_t[i] = tc
            if tn is None:
                break
            if tn - last_t[i] >= refractory_s:
                out.append((i, tn, pn, True))
                last_t[i] = tn
                lref[i] = lb
            ta, la = tb, lb
    return out, lref, last_t


@pytest.mark.parametrize("refractory_s", [0.0, 0.003])
def test_sensor_interval_kernel_matches_reference(refractory_s):
    from evedge.sim._sensor import _sensor_interval

    rng = np.random.default_rng(5)
    n = 300
    l0 = rng.uniform(-3, 0, n)
    l1 = l0 + rng.normal(0, 0.5, n) * (rng.random(n) < 0.7)
    cpos, cneg = rng.uniform(0.1, 0.3, n), rng.uniform(0.1, 0.3, n)
    lref = l0 + rng.uniform(-0.9, 0.9, n) * np.minimum(cpos, cneg)
    last = np.where(rng.random(n) < 0.5, -np.inf, rng.uniform(0.99, 1.0, n))
    t0, t1 = 1.0, 1.01
    npix = np.sort(rng.choice(n, 80))
    nt = rng.uniform(t0, t1, 80)
    order = np.lexsort((nt, npix))
    npix, nt, npol = npix[order], nt[order], rng.random(80) < 0.5
    want, wl, wlast = ref_sensor_interval(l0, l1, t0, t1, lref, cpos, cneg, last, refractory_s,
                                          list(zip(npix.tolist(), nt.tolist(), npol.tolist())))
    state = [lref.copy(), last.copy(), np.zeros(n, np.int64)]
    args = (l0, l1, t0, t1, state[0], cpos, cneg, state[1], refractory_s, state[2], 0.0, np.uint64(1), npix, nt,
            npol, npix.shape[0])
    e, b = np.empty(0), np.empty(0, bool)
    m = _sensor_interval(*args, False, np.empty(0, np.int64), e, e, b, b)
    assert m == len(want) > 100 and any(w[3] for w in want)
    out = (np.empty(m, np.int64), np.empty(m), np.empty(m), np.empty(m, bool), np.empty(m, bool))
    assert _sensor_interval(*args, True, *out) == m
    np.testing.assert_array_equal(out[0], [w[0] for w in want])
    np.testing.assert_allclose(out[1], [w[1] for w in want], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out[3], [w[2] for w in want])
    np.testing.assert_array_equal(out[4], [w[3] for w in want])
    np.testing.assert_allclose(state[0], wl, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(state[1], wlast)
