"""Frames and video in: ESIM's algorithm (against a reference written here), readers, upsampling, errors."""


import numpy as np
import pytest

from evedge.sim import ConverterParams, EventConverter, parse_scene, render_frame
from evedge.sim.frames import (FramesError, FramesRenderer, frames_from_arrays, open_frames_folder, open_video,
                               read_timestamps, simulate_frames)

EPS = 1e-3


def esim_reference(frames, times_s, c_pos, c_neg, refractory_s=0.0, eps=EPS):
    """ESIM's ``EventSimulator::imageCallback`` (esim_py) in plain Python, without threshold noise.

    Per pixel: the reference starts at the first frame's log intensity; for
    each new frame with ``|L1 - L0| > 1e-6``, levels ``ref + pol C`` strictly
    beyond ``L0`` and up to ``L1`` are crossed at the linearly interpolated
    time; a crossing sooner than the refractory period after the pixel's last
    event is not emitted (the reference still moves).
    """
    logs = [np.log(f + eps) for f in frames]
    ref = logs[0].copy()
    last = np.full(ref.shape, -np.inf)
    out = []
    for k in range(1, len(frames)):
        l0, l1 = logs[k - 1], logs[k]
        t0, dt = times_s[k - 1], times_s[k] - times_s[k - 1]
        for y in range(ref.shape[0]):
            for x in range(ref.shape[1]):
                it, itdt = l0[y, x], l1[y, x]
                if abs(it - itdt) <= 1e-6:
                    continue
                pol = 1.0 if itdt >= it else -1.0
                c = c_pos if pol > 0 else c_neg
                cross = ref[y, x]
                while True:
                    cross += pol * c
                    if (pol > 0 and it < cross <= itdt) or (pol < 0 and itdt <= cross < it):
                        t = t0 + (cross - it) / (itdt - it) * dt
                        if t - last[y, x] >= refractory_s:
                            out.append((x, y, t, pol > 0))
                            last[y, x] = t
                        ref[y, x] = cross
                    else:
                        break
    return out


def _rendered_frames(n=60, rate_hz=1000.0, size=(26, 14)):
    d = {
        "scene": {"kind": "shapes", "duration_s": 1.0, "background": 0.8},
        "sensor": {"width": size[0], "height": size[1]},
        "motion": {"velocity_px_s": [180.0, -60.0]},
        "shapes": [{"kind": "star", "center_px": [9, 7], "radius_px": 6, "intensity": 0.15},
                   {"kind": "circle", "center_px": [19, 8], "radius_px": 3.5, "intensity": 0.35}],
    }
    if size[0] > 60:  # and a shape far down the image (in the second tile of pixels of _frames_batch)
        d["shapes"].append({"kind": "circle", "center_px": [size[0] - 12, size[1] - 9], "radius_px": 6,
                            "intensity": 0.3})
    scene = parse_scene(d, "f.toml")
    t = np.arange(n) / rate_hz
    return np.stack([render_frame(scene, float(tk)) for tk in t]), t


def _per_pixel(x, y, t, p):
    out = {}
    for xi, yi, ti, pi in zip(x, y, t, p):
        out.setdefault((int(xi), int(yi)), []).append((float(ti), bool(pi)))
    return {k: sorted(v) for k, v in out.items()}


@pytest.mark.parametrize("refractory_us", [0.0, 300.0])
def test_frames_match_esim_reference(refractory_us):
    frames, t = _rendered_frames()
    params = ConverterParams(contrast_pos=0.18, contrast_neg=0.22, refractory_us=refractory_us)
    rec = simulate_frames(frames_from_arrays(frames, t), params, progress=False)
    want = esim_reference(frames, t, 0.18, 0.22, refractory_us * 1e-6)
    assert len(want) > 300
    assert rec.events.shape[0] == len(want)
    got = _per_pixel(rec.events["x"], rec.events["y"], rec.truth["t_ns"] * 1e-9, rec.events["p"])
    ref = _per_pixel(*zip(*want))
    assert got.keys() == ref.keys()
    dt = []
    for key in ref:
        assert [p for _, p in got[key]] == [p for _, p in ref[key]]
        dt += [abs(a[0] - b[0]) * 1e6 for a, b in zip(got[key], ref[key])]
    assert np.median(dt) <= 0.5 and max(dt) < 0.001  # ns output of the same algorithm
    assert np.all(np.abs(rec.events["t"] - rec.truth["t_ns"] / 1e3) <= 0.5 + 1e-9)
    assert np.all(rec.truth["is_signal"]) and np.all(np.isnan(rec.truth["vx_px_s"]))


def test_pixel_model_is_the_scenes_one_and_chunking_does_not_matter():
    frames, t = _rendered_frames(40)
    params = ConverterParams(contrast_sigma=0.05, noise_rate_hz=30.0, refractory_us=200.0, jitter_us=5.0)
    a = simulate_frames(frames_from_arrays(frames, t), params, seed=4, progress=False, chunk_s=1.0)
    b = simulate_frames(frames_from_arrays(frames, t), params, seed=4, progress=False, chunk_s=0.0037)
    assert a.events.tobytes() == b.events.tobytes() and a.truth.tobytes() == b.truth.tobytes()
    assert (~a.truth["is_signal"]).sum() > 5
    c = simulate_frames(frames_from_arrays(frames, t), params, seed=5, progress=False)
    assert c.events.tobytes() != a.events.tobytes()
    sig = a.truth["is_signal"]
    for key, ev in _per_pixel(a.events["x"][sig], a.events["y"][sig], a.truth["t_ns"][sig] * 1e-9,
                              a.events["p"][sig]).items():
        gaps = np.diff([e[0] for e in ev])
        assert np.all(gaps >= 200e-6 - 1e-9)  # refractory (jitter only delays)


def test_log_input_and_log_upsampling_keep_the_times():
    frames, t = _rendered_frames(30)
    # 8-bit levels as in a video: no pixel changes by a rounding error only (where a crossing's instant
    # inside the frame interval is arbitrary)
    frames = np.rint(frames * 255) / 255
    base = simulate_frames(frames_from_arrays(frames, t), progress=False)
    logged = simulate_frames(frames_from_arrays(np.log(frames + EPS), t), log_input=True, progress=False)
    up = simulate_frames(frames_from_arrays(frames, t), upsample=4, interpolation="log", progress=False)
    want = _per_pixel(base.events["x"], base.events["y"], base.truth["t_ns"], base.events["p"])
    for other in (logged, up):
        got = _per_pixel(other.events["x"], other.events["y"], other.truth["t_ns"], other.events["p"])
        assert got.keys() == want.keys()
        for key in want:
            assert [p for _, p in got[key]] == [p for _, p in want[key]]
            assert max(abs(a[0] - b[0]) for a, b in zip(got[key], want[key])) <= 2  # ns: rounding only
    assert up.metadata["n_samples"] == 4 * base.metadata["n_samples"]


def test_flow_upsampling_moves_edges_between_frames():
    """The mid sub-frame of a texture shifting 4 px per frame is the 2 px shift, not a cross-fade."""
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(0)
    big = gaussian_filter(rng.uniform(size=(60, 120)), 2.0)
    big = 0.15 + 0.7 * (big - big.min()) / np.ptp(big)
    crop = lambda dx: big[6:54, 20 - dx:84 - dx]  # noqa: E731  (content moves right by dx)
    frames = np.stack([crop(0), crop(4), crop(8)])
    t = np.array([0.0, 0.01, 0.02])
    truth = crop(2)[8:-8, 8:-8]
    err = {}
    for interp in ("log", "flow"):
        r = FramesRenderer(frames_from_arrays(frames, t), upsample=2, interpolation=interp)
        assert r.next_sample_s(0.0) == 0.005
        mid = r.intensity(0.005)[8:-8, 8:-8]
        err[interp] = np.abs(mid - truth).mean()
    assert err["flow"] < 0.4 * err["log"], err
    params = ConverterParams(contrast_pos=0.1, contrast_neg=0.1)
    rec = simulate_frames(frames_from_arrays(frames, t), params, upsample=4, interpolation="flow", progress=False)
    assert rec.events.shape[0] > 100 and rec.metadata["interpolation"] == "flow"


def _write_video(path, frames_u8, fps):
    import cv2

    wr = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), fps, (frames_u8.shape[2], frames_u8.shape[1]),
                         isColor=False)
    assert wr.isOpened()
    for f in frames_u8:
        wr.write(f)
    wr.release()


def test_video_and_folder_read_like_arrays(tmp_path):
    import cv2

    frames, _ = _rendered_frames(12)
    u8 = np.rint(frames * 255).astype(np.uint8)
    _write_video(tmp_path / "v.avi", u8, 250.0)
    ref = simulate_frames(frames_from_arrays(u8, np.arange(12) / 250.0), progress=False)
    assert ref.events.shape[0] > 50
    vid = simulate_frames(open_video(tmp_path / "v.avi"), progress=False)  # container times, 4 ms apart
    assert vid.events.tobytes() == ref.events.tobytes()
    folder = tmp_path / "frames"
    folder.mkdir()
    for k, f in enumerate(u8):
        cv2.imwrite(str(folder / f"{k:04d}.png"), cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))  # colour: read as grey
    (folder / "timestamps.txt").write_text("# t [s]\n" + "".join(f"{k / 250.0 + 3.0}\n" for k in range(12)))
    src = open_frames_folder(folder)
    assert src.times_s[0] == 3.0
    fold = simulate_frames(src, progress=False)
    assert fold.events.tobytes() == ref.events.tobytes() and fold.metadata["first_frame_s"] == 3.0
    rate = simulate_frames(open_frames_folder(folder, rate_hz=250.0), progress=False)
    assert rate.events.tobytes() == ref.events.tobytes()
    # an Event Camera Dataset folder: images/ with images.txt ("t images/name.png") beside it
    (folder / "timestamps.txt").unlink()
    (tmp_path / "images.txt").write_text("".join(f"{k / 250.0:.9f} frames/{k:04d}.png\n" for k in range(12)))
    ecd = simulate_frames(open_frames_folder(folder), progress=False)
    assert ecd.events.tobytes() == ref.events.tobytes()


def test_bad_inputs_are_named(tmp_path):
    with pytest.raises(FramesError, match="nope.avi: no such video file"):
        open_video(tmp_path / "nope.avi")
    (tmp_path / "junk.mp4").write_text("not a video")
    with pytest.raises(FramesError, match="junk.mp4"):
        open_video(tmp_path / "junk.mp4")
    ts = tmp_path / "ts.txt"
    ts.write_text("0.0\n0.1\nabc\n")
    with pytest.raises(FramesError, match="ts.txt: line 3: expected a time in seconds, got 'abc'"):
        read_timestamps(ts)
    ts.write_text("0.0\n0.2\n0.1\n")
    with pytest.raises(FramesError, match="frame 2 at 0.1 s follows 0.2 s"):
        read_timestamps(ts)
    folder = tmp_path / "f"
    folder.mkdir()
    with pytest.raises(FramesError, match="need at least 2 images"):
        open_frames_folder(folder)
    import cv2

    for k in range(3):
        cv2.imwrite(str(folder / f"{k}.png"), np.zeros((4, 5), np.uint8))
    with pytest.raises(FramesError, match="no frame times"):
        open_frames_folder(folder)
    ts.write_text("0\n1\n")
    with pytest.raises(FramesError, match="3 frames but 2 timestamps"):
        open_frames_folder(folder, timestamps=ts)
    cv2.imwrite(str(folder / "3.png"), np.zeros((5, 5), np.uint8))
    src = open_frames_folder(folder, rate_hz=10.0)
    with pytest.raises(FramesError, match="3.png|frame 3 is 5x5, expected 5x4"):
        simulate_frames(src, progress=False)
    with pytest.raises(ValueError, match="interpolation must be one of"):
        FramesRenderer(src, interpolation="cubic")


def test_non_finite_frames_are_named():
    frames, t = _rendered_frames(6)
    bad = frames.copy()
    bad[3, 2, 5] = np.nan
    with pytest.raises(ValueError, match=r"clip.npy: the sample at t = 0.003 s has 1 non-finite pixel values"):
        simulate_frames(frames_from_arrays(bad, t, name="clip.npy"), progress=False)
    bad = frames.copy()
    bad[0, 0, 0] = np.inf
    with pytest.raises(ValueError, match="clip.npy: the first sample has 1 non-finite"):
        simulate_frames(frames_from_arrays(bad, t, name="clip.npy"), progress=False)


def test_frames_api_refuses_bad_arguments(tmp_path):
    frames, t = _rendered_frames(4)
    with pytest.raises(FramesError, match="clip: 4 frames but times_s has shape \\(3,\\)"):
        frames_from_arrays(frames, t[:3], name="clip")
    with pytest.raises(FramesError, match="frame 2 at 0.001 s follows 0.002 s"):
        frames_from_arrays(frames, [0.0, 0.002, 0.001, 0.003])
    with pytest.raises(FramesError, match="expected frames of shape \\(n, height, width\\)"):
        frames_from_arrays(frames[0], t)
    with pytest.raises(TypeError, match="source must be a FrameSource"):
        simulate_frames(frames, progress=False)
    with pytest.raises(TypeError, match="params must be a ConverterParams"):
        simulate_frames(frames_from_arrays(frames, t), {"contrast_pos": 0.2}, progress=False)
    with pytest.raises(ValueError, match="upsample must be an integer in 1..1000"):
        simulate_frames(frames_from_arrays(frames, t), upsample=0, progress=False)
    import cv2

    for k in range(2):
        cv2.imwrite(str(tmp_path / f"{k}.png"), np.zeros((3, 3), np.uint8))
    with pytest.raises(FramesError, match="rate_hz must be a positive number, got -1.0"):
        open_frames_folder(tmp_path, rate_hz=-1.0)
    with pytest.raises(FramesError, match="give timestamps or rate_hz, not both"):
        open_frames_folder(tmp_path, rate_hz=10.0, timestamps=np.array([0.0, 1.0]))


# --------------------------------------------------------------------------- damaged files, bounds (issue 14)
def _png(width, height, rows):
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    raw = zlib.compress(b"".join(b"\0" + bytes(width) for _ in range(rows)))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", raw) + chunk(b"IEND", b""))


def _folder(tmp_path, n=3, ext=".png"):
    import cv2

    folder = tmp_path / "frames"
    folder.mkdir(parents=True)
    for k in range(n):
        cv2.imwrite(str(folder / f"{k}{ext}"), np.full((4, 5), 40 * k + 20, np.uint8))
    (folder / "timestamps.txt").write_text("".join(f"{k / 100}\n" for k in range(n)))
    return folder


def test_declared_frame_sizes_are_checked_before_decoding(tmp_path, monkeypatch):
    import cv2

    folder = _folder(tmp_path)
    decoded = []
    real = cv2.imdecode
    monkeypatch.setattr(cv2, "imdecode", lambda *a: decoded.append(1) or real(*a))
    # 2^30 pixels declared in 100 bytes: OpenCV would allocate 1 GiB, then raise its own assertion (no FramesError)
    (folder / "0.png").write_bytes(_png(32768, 32768, 1))
    with pytest.raises(FramesError, match=r"0.png: frame size 32768x32768 is outside 1..32767"):
        open_frames_folder(folder)
    (folder / "0.png").write_bytes(_png(30000, 30000, 1))  # inside the side bound: the memory check refuses it
    from evedge import _resources
    monkeypatch.setattr(_resources, "available_memory_bytes", lambda: 2**30)
    with pytest.raises(FramesError, match=r"0.png: frames of 30000x30000 needs about .* GiB; this machine has 1 GiB"):
        open_frames_folder(folder)
    assert decoded == []
    # a later frame that declares another size is refused before it is decoded
    cv2.imwrite(str(folder / "0.png"), np.zeros((4, 5), np.uint8))
    (folder / "2.png").write_bytes(_png(20000, 20000, 1))
    src = open_frames_folder(folder)
    with pytest.raises(FramesError, match=r"2.png: frame 2 is 20000x20000, expected 5x4 like the first frame"):
        simulate_frames(src, progress=False)
    assert len(decoded) == 3  # frame 0 when opened, frames 0 and 1 in the run: never frame 2


def test_damaged_images_are_named_errors(tmp_path):
    import cv2

    folder = _folder(tmp_path, ext=".jpg")
    img = (np.random.default_rng(0).random((4, 5)) * 255).astype(np.uint8)
    cv2.imwrite(str(folder / "1.jpg"), img)
    data = (folder / "1.jpg").read_bytes()
    (folder / "1.jpg").write_bytes(data[:-100] + bytes(100))  # a zeroed tail: OpenCV alone decodes other pixels
    assert not np.array_equal(cv2.imread(str(folder / "1.jpg"), cv2.IMREAD_GRAYSCALE), cv2.imdecode(
        np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE))
    with pytest.raises(FramesError, match=r"1.jpg: the JPEG ends before its end-of-image marker"):
        simulate_frames(open_frames_folder(folder), progress=False)
    (folder / "1.jpg").write_bytes(b"\xff\xd8 not a jpeg")
    with pytest.raises(FramesError, match=r"1.jpg: not a readable image \(unknown or damaged header\)"):
        simulate_frames(open_frames_folder(folder), progress=False)
    png = _folder(tmp_path / "p")
    (png / "1.png").write_bytes(_png(5, 4, 2))  # rows missing: libpng's error, as a named error
    with pytest.raises(FramesError, match=r"1.png: OpenCV cannot read it as an image"):
        simulate_frames(open_frames_folder(png), progress=False)
    tif = _folder(tmp_path / "t", ext=".tiff")
    bad = np.full((4, 5), 0.5, np.float32)
    bad[1, 2] = np.nan
    cv2.imwrite(str(tif / "2.tiff"), bad)
    with pytest.raises(FramesError, match=r"2.tiff: float pixels must be finite and >= 0"):
        simulate_frames(open_frames_folder(tif), progress=False)


def test_frame_times_are_bounded_and_a_long_gap_is_not_many_chunks(tmp_path):
    folder = _folder(tmp_path)
    # 9.3e9 s: the truth's t_ns (int64 ns) would overflow; refused, naming the file
    (folder / "timestamps.txt").write_text("0\n1\n9.3e9\n")
    with pytest.raises(FramesError, match=r"timestamps.txt: frame times span 9300000000.0 s, more than 9e\+09 s"):
        open_frames_folder(folder)
    # 8e9 s between two frames: one chunk (the loop used to take 1.6e11 steps of chunk_s)
    (folder / "timestamps.txt").write_text("0\n0.01\n8e9\n")
    rec = simulate_frames(open_frames_folder(folder), progress=False, chunk_s=0.05)
    ev, tr = rec.events, rec.truth
    assert ev.shape[0] > 0 and ev["t"][-1] > 1e12  # events in the long interval
    assert np.all(np.abs(tr["t_ns"] - ev["t"] * 1000) <= 500 + 2e9 * np.spacing(8e9))
    # the chunking still does not change the output
    again = simulate_frames(open_frames_folder(folder), progress=False, chunk_s=1e9)
    assert again.events.tobytes() == ev.tobytes() and again.truth.tobytes() == tr.tobytes()


def test_noise_over_long_frame_times_is_refused_before_work(tmp_path):
    folder = _folder(tmp_path)
    (folder / "timestamps.txt").write_text("0\n1\n8e9\n")
    with pytest.raises(FramesError, match=r"frames: 5x4 for 8e\+09 s of frames \(about 1.6e\+12 noise events at "
                                          r"noise_rate_hz=10\) needs about .* GiB"):
        simulate_frames(open_frames_folder(folder), ConverterParams(noise_rate_hz=10.0), progress=False)


def test_video_decoder_errors_are_named(tmp_path):
    frames, _ = _rendered_frames(6)
    _write_video(tmp_path / "v.avi", np.rint(frames * 255).astype(np.uint8), 250.0)
    data = (tmp_path / "v.avi").read_bytes()
    (tmp_path / "cut.avi").write_bytes(data[:300])
    with pytest.raises(FramesError, match=r"cut.avi: (OpenCV cannot open it as a video|no decodable frame)"):
        open_video(tmp_path / "cut.avi")


def test_a_png_chunk_length_past_the_end_is_refused_before_opencv(tmp_path):
    folder = _folder(tmp_path)
    data = bytearray((folder / "1.png").read_bytes())
    data[33] ^= 0xA7  # the first chunk after IHDR now claims ~2.8 GB: OpenCV spends seconds on it
    (folder / "1.png").write_bytes(bytes(data))
    with pytest.raises(FramesError, match=r"1.png: PNG chunk b'.{4}' at byte 33 claims \d+ bytes past the end"):
        simulate_frames(open_frames_folder(folder), progress=False)
    data[33] ^= 0xA7
    data[45] ^= 0x01  # a byte of the (IDAT) chunk's body: PIL reads the header only
    (folder / "1.png").write_bytes(bytes(data))
    with pytest.raises(FramesError, match=r"1.png: PNG chunk .* at byte 33 fails its CRC"):
        simulate_frames(open_frames_folder(folder), progress=False)


@pytest.mark.parametrize("case", ["plain", "pixel_model", "log_upsample", "log_upsample_odd", "flow_upsample",
                                  "log_input", "log_input_upsample", "uint8", "resize"])
def test_batches_of_frames_give_the_events_of_frame_by_frame(case, monkeypatch):
    """The fused batch kernel (one call per batch of frames) against the converter's frame-by-frame path."""
    # more events per batch than the first buffers hold (they grow)
    frames, t = _rendered_frames(70, rate_hz=2000.0, size=(72, 48))
    params = ConverterParams(contrast_pos=0.15, contrast_neg=0.17)
    kw = {}
    if case == "pixel_model":
        params = ConverterParams(contrast_sigma=0.05, noise_rate_hz=40.0, refractory_us=150.0, jitter_us=3.0)
    elif case == "log_upsample":
        kw = dict(upsample=3, interpolation="log")
    elif case == "log_upsample_odd":  # rows of the batch not 64-byte aligned (405 float64 per frame)
        frames, t = _rendered_frames(70, rate_hz=2000.0, size=(27, 15))
        frames = np.repeat(frames, 3, axis=0)[:70] * np.linspace(0.7, 1.0, 70)[:, None, None]
        kw = dict(upsample=5, interpolation="log")
    elif case == "flow_upsample":
        kw = dict(upsample=2, interpolation="flow")
    elif case == "log_input":
        frames, kw = np.log(frames + EPS), dict(log_input=True)
    elif case == "log_input_upsample":
        frames, kw = np.log(frames + EPS), dict(log_input=True, upsample=2)
    elif case == "uint8":
        frames = np.rint(frames * 255).astype(np.uint8)
    elif case == "resize":
        kw = dict(resize=(80, 36))
    runs = {}
    steps = []  # log upsampling takes the log-interval kernel (no sub-frame images)
    step = EventConverter._log_interval_step
    monkeypatch.setattr(EventConverter, "_log_interval_step", lambda self, got: steps.append(step(self, got))
                        or steps[-1])
    for mode in ("batched", "per_frame"):
        if mode == "per_frame":
            monkeypatch.setattr(FramesRenderer, "samples", None)  # the converter then steps frame by frame
        for chunk_s in (0.05, 0.0031):
            runs[mode, chunk_s] = simulate_frames(frames_from_arrays(frames, t), params, seed=3, progress=False,
                                                  chunk_s=chunk_s, **kw)
    ref = runs["per_frame", 0.05]
    assert ref.events.shape[0] > 1200  # one batch at chunk_s = 0.05: more than the first buffers (1024)
    # the log-interval kernel skips log(exp(L) - eps + eps): the same bytes here (the stored us and ns times hide
    # the last-bit differences of the float times; see _log_interval)
    assert any(steps) == (kw.get("upsample", 1) > 1 and kw.get("interpolation", "log") == "log"), case
    for key, rec in runs.items():
        assert rec.events.tobytes() == ref.events.tobytes(), key
        assert rec.truth.tobytes() == ref.truth.tobytes(), key
        assert rec.metadata["n_samples"] == ref.metadata["n_samples"], key


def test_batches_stop_at_the_chunk_and_the_batch_size():
    """``samples`` follows next_sample_s: up to the first sample at or after ``until_s``, at most ``max_n``."""
    frames, t = _rendered_frames(12, rate_hz=100.0)
    r = FramesRenderer(frames_from_arrays(frames, t), upsample=3)
    times, images = r.samples(0.0, 0.025, 100)
    want, tk = [], 0.0
    while tk < 0.025:
        tk = r.next_sample_s(tk)
        want.append(tk)
    assert times.tolist() == want and images.shape == (len(want), 14, 26)
    assert np.array_equal(images[-1], r.intensity(want[-1]))
    times, _ = r.samples(0.0, 1.0, 4)
    assert times.shape == (4,)
    times, _ = r.samples(0.1, 1.0, 100)
    assert times[-1] == t[-1] - t[0]


def test_non_finite_frame_inside_a_batch_is_named():
    frames, t = _rendered_frames(40)
    frames[17, 3, 4] = np.inf
    frames[17, 5, 6] = np.nan
    frames[25, 0, 0] = np.nan
    with pytest.raises(ValueError, match=r"clip: the sample at t = 0.017 s has 2 non-finite pixel values"):
        simulate_frames(frames_from_arrays(frames, t, name="clip"), progress=False)
    # log upsampling: the log-interval kernel stops at the interval and the image path names its first sample
    frames[17, 3, 4] = 0.5
    frames[25, 0, 0] = 0.5
    with pytest.raises(ValueError, match=r"clip: the sample at t = 0.016333333333333335 s has 1 non-finite pixel"):
        simulate_frames(frames_from_arrays(frames, t, name="clip"), upsample=3, progress=False)


def test_gen4_frames_memory_is_bounded():
    """Frames resized to 1280x720 (``--sensor gen4``): the working memory is the per-pixel state and one batch.

    Traced peak minus the output, for 6 and for 12 frames: the same (it does not grow
    with the input) and under 200 MiB (per-pixel state, the pair of frames, the batch
    of samples and the sort of the output at 0.92 Mpx).
    """
    import tracemalloc

    frames, t = _rendered_frames(12, rate_hz=500.0)
    simulate_frames(frames_from_arrays(frames[:3], t[:3]), resize=(1280, 720), progress=False)  # compile
    extra = []
    for n in (6, 12):
        tracemalloc.start()
        rec = simulate_frames(frames_from_arrays(frames[:n], t[:n]), resize=(1280, 720), progress=False,
                              chunk_s=0.004)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert rec.sensor_size.width == 1280 and rec.events.shape[0] > 10_000
        extra.append((peak - 2 * (rec.events.nbytes + rec.truth.nbytes)) / 2**20)
    assert max(extra) < 200, extra
    assert abs(extra[1] - extra[0]) < 25, extra


@pytest.mark.parametrize("fourcc, suffix", [("FFV1", ".avi"), ("MJPG", ".avi"), ("mp4v", ".mp4")])
def test_video_opened_in_one_decoding(tmp_path, monkeypatch, fourcc, suffix):
    """The container's times from its packets (no decoding) equal a decoding pass's; grey streams read unconverted."""
    import cv2

    import evedge.sim.frames as fr

    frames, _ = _rendered_frames(10)
    u8 = np.rint(frames * 255).astype(np.uint8)
    path = tmp_path / f"v{suffix}"
    wr = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), 250.0, (u8.shape[2], u8.shape[1]), isColor=False)
    assert wr.isOpened()
    for f in u8:
        wr.write(f)
    wr.release()
    decoded = []
    cap = cv2.VideoCapture(str(path))
    while cap.grab():
        decoded.append(cap.get(cv2.CAP_PROP_POS_MSEC) * 1e-3)
    cap.release()
    packets = fr._container_times(path, cv2)
    assert packets is not None and packets.tobytes() == np.array(decoded).tobytes()
    fast = open_video(path)
    # the fallback (no usable packet times) gives the same source, and the unconverted grey the same frames
    monkeypatch.setattr(fr, "_container_times", lambda p, c: None)
    slow = open_video(path)
    assert fast.times_s.tobytes() == slow.times_s.tobytes() and len(fast) == 10
    assert fast._reader.grey == (fourcc == "FFV1")  # FFV1 grey is Y800; the others decode to YUV 4:2:0
    slow._reader.grey = False
    for k in range(10):
        assert fast.frame(k).tobytes() == slow.frame(k).tobytes()
    if fourcc == "FFV1":  # lossless: the frames as written
        assert fast.frame(3).tobytes() == (u8[3] / 255.0).tobytes()
    fast.close(), slow.close()


def test_a_video_cut_mid_stream_is_named(tmp_path):
    frames, _ = _rendered_frames(12)
    _write_video(tmp_path / "v.avi", np.rint(frames * 255).astype(np.uint8), 250.0)
    data = (tmp_path / "v.avi").read_bytes()
    (tmp_path / "cut.avi").write_bytes(data[:len(data) * 2 // 3])
    try:
        rec = simulate_frames(open_video(tmp_path / "cut.avi"), progress=False)
    except FramesError as err:
        assert "cut.avi" in str(err)
    else:  # the complete frames before the cut
        assert 2 <= rec.metadata["n_frames"] < 12


def test_log_interval_steps_mixed_with_image_batches(monkeypatch):
    """When the renderer declines a log interval (here: from a sample inside a frame interval, after a log step
    that stopped there at a chunk's end), the image path resumes from the present sample rebuilt from the log
    frames: the same bytes as frame by frame."""
    frames, t = _rendered_frames(40, rate_hz=2000.0, size=(40, 30))
    params = ConverterParams(contrast_pos=0.15, contrast_neg=0.17, refractory_us=50.0)
    ref = simulate_frames(frames_from_arrays(frames, t), params, upsample=4, progress=False, chunk_s=0.00107)
    calls = []
    real = FramesRenderer.log_interval

    def at_frames_only(self, t_s, until_s):
        inside = t_s not in set(t - t[0])
        calls.append(inside)
        return None if inside else real(self, t_s, until_s)

    monkeypatch.setattr(FramesRenderer, "log_interval", at_frames_only)
    mixed = simulate_frames(frames_from_arrays(frames, t), params, upsample=4, progress=False, chunk_s=0.00107)
    assert sum(calls) > 10 and not all(calls) and ref.events.shape[0] > 500
    assert mixed.events.tobytes() == ref.events.tobytes() and mixed.truth.tobytes() == ref.truth.tobytes()
    monkeypatch.setattr(FramesRenderer, "samples", None)  # frame by frame
    per_frame = simulate_frames(frames_from_arrays(frames, t), params, upsample=4, progress=False, chunk_s=0.00107)
    assert per_frame.events.tobytes() == ref.events.tobytes() and per_frame.truth.tobytes() == ref.truth.tobytes()
