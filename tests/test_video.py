"""evedge.video: edge and event frames (colours, overlay, scale, caption, window), MP4/GIF writing, CLI."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from evedge.cli import main
from evedge.events import Frames, Recording, SensorSize, make_events
from evedge.video import (LIFETIME_RANGE_US, OFF_RGB, ON_RGB, edge_png, edge_video_frames, event_video_frames,
                          write_video)

SENSOR = SensorSize(12, 8)


def _body(frame, scale=1):
    """The frame without its caption bar, downsampled back to sensor pixels (top-left of each block)."""
    h = SENSOR.height * scale
    return frame[-h:][::scale, ::scale]


def test_edge_png_is_black_on_white():
    edges = np.zeros((3, 4), bool)
    edges[1, 2] = True
    png = edge_png(edges)
    assert png.dtype == np.uint8 and png[1, 2] == 0 and (png[edges == 0] == 255).all()
    with pytest.raises(TypeError, match="boolean edge map"):
        edge_png(np.zeros((2, 2)))


def test_mono_edges_on_white_and_over_grey_upscaled():
    edge = np.zeros(SENSOR.shape, bool)
    edge[2, 3] = edge[5, 9] = True
    edges = Frames([100, 200], np.stack([edge, edge]))
    frame = next(edge_video_frames(edges, colour="mono", scale=3))
    assert frame.shape[1] == 36 and frame.shape[0] > 24  # caption bar on top
    body = frame[-24:]
    assert (body[6:9, 9:12] == 0).all()  # one edge pixel = a 3x3 black block
    assert (_body(frame, 3)[~edge] == 255).all()
    grey = Frames([0, 150], np.stack([np.full(SENSOR.shape, 40, np.uint8), np.full(SENSOR.shape, 90, np.uint8)]))
    f0, f1 = edge_video_frames(edges, grey=grey, colour="mono", scale=1)
    assert (_body(f0)[~edge] == 40).all() and (_body(f1)[~edge] == 90).all()  # the latest grey frame at or before t
    assert (_body(f1)[edge] == (255, 40, 40)).all()


def test_lifetime_and_polarity_colours_follow_the_latest_event():
    import cv2

    ev = make_events([3, 3, 9], [2, 2, 5], [10, 50, 60], [1, 0, 1])
    life = np.array([LIFETIME_RANGE_US[1], LIFETIME_RANGE_US[0], 1e9])
    edge = np.zeros(SENSOR.shape, bool)
    edge[2, 3] = edge[5, 9] = True
    edges = Frames([40, 100], np.stack([edge, edge]))
    viridis = cv2.applyColorMap(np.array([[0], [255]], np.uint8), cv2.COLORMAP_VIRIDIS)[:, 0, ::-1]
    f40, f100 = edge_video_frames(edges, events=ev, lifetime_us=life, colour="lifetime", scale=1)
    assert (_body(f40)[2, 3] == viridis[1]).all()       # at t=40 the latest event of (3, 2) has 100 ms
    assert (_body(f100)[2, 3] == viridis[0]).all()      # at t=100 the one of t=50 with 0.1 ms
    assert (_body(f100)[5, 9] == viridis[1]).all()      # clipped at the top of the scale
    p40, p100 = edge_video_frames(edges, events=ev, colour="polarity", scale=1)
    assert (_body(p40)[2, 3] == ON_RGB).all() and (_body(p100)[2, 3] == OFF_RGB).all()
    with pytest.raises(ValueError, match="colour='lifetime' needs events and lifetime_us"):
        next(edge_video_frames(edges, colour="lifetime"))


def test_event_frames_window_is_half_open():
    ev = make_events([1, 2, 3, 3], [1, 1, 1, 1], [0, 1, 5, 10], [1, 1, 1, 0])
    frame = next(event_video_frames(ev, SENSOR, [10], window_us=9, scale=1))
    body = _body(frame)
    assert (body[1, 1] == 255).all()          # t=0 is not in (1, 10]... nor t=1
    assert (body[1, 2] == 255).all()
    assert (body[1, 3] == OFF_RGB).all()      # t=5 ON then t=10 OFF: the latest wins
    assert (body[0] == 255).all()


def test_mp4_and_gif_round_trip_and_atomic_failure(tmp_path):
    import cv2
    from PIL import Image

    edge = np.zeros(SENSOR.shape, bool)
    edge[2:6, 4] = True
    frames = list(edge_video_frames(Frames([0, 1, 2], np.stack([edge] * 3)), colour="mono", scale=10))
    mp4 = write_video(tmp_path / "a.mp4", frames, fps=10)
    cap = cv2.VideoCapture(str(mp4))
    ok, first = cap.read()
    assert ok and cap.get(cv2.CAP_PROP_FRAME_COUNT) == 3
    h, w = frames[0].shape[:2]
    assert first.shape[:2] == (h + h % 2, w + w % 2)
    assert np.abs(first[:h, :w, ::-1].astype(int) - frames[0]).mean() < 8  # lossy codec, close
    gif = write_video(tmp_path / "a.gif", frames, fps=10)
    with Image.open(gif) as im:
        assert im.n_frames == 3 and im.size == (w, h)
        assert np.array_equal(np.asarray(im.convert("RGB")), frames[0])
    bad = frames[:2] + [frames[2][:-1]]
    with pytest.raises(ValueError, match="frame 2 is"):
        write_video(tmp_path / "b.mp4", bad)
    with pytest.raises(ValueError, match="expected a .mp4 or .gif"):
        write_video(tmp_path / "b.avi", frames)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.gif", "a.mp4"]


def test_render_and_detect_video_cli(tmp_path):
    from evedge.io import write_events

    rng = np.random.default_rng(0)
    n = 3000
    size = SensorSize(40, 30)
    # a vertical edge sweeping right at 400 px/s over 80 ms, plus noise
    t = np.sort(rng.integers(0, 80_000, n))
    x = np.clip((t * 400e-6).astype(int) + rng.integers(0, 2, n), 0, 39)
    ev = make_events(x, rng.integers(0, 30, n), t, np.ones(n, bool))
    grey = Frames([0, 40_000, 80_000], rng.integers(0, 256, (3, 30, 40), dtype=np.uint8))
    src = write_events(tmp_path / "rec", Recording(ev, size, frames=grey))
    runner = CliRunner()
    res = runner.invoke(main, ["render", str(src), "-o", str(tmp_path / "e.mp4"), "--fps", "100", "--quiet"])
    assert res.exit_code == 0, res.output
    assert "8 frames" in res.output
    res = runner.invoke(main, ["detect", str(src), "-o", str(tmp_path / "d"), "--at-frames",
                               "--video", str(tmp_path / "d.gif"), "--quiet"])
    assert res.exit_code == 0, res.output
    from PIL import Image

    with Image.open(tmp_path / "d.gif") as im:
        assert im.n_frames == 3
    res = runner.invoke(main, ["render", str(tmp_path / "d" / "detection.h5"), "-o", str(tmp_path / "edges.gif"),
                               "--edges", "--quiet"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(main, ["render", str(src), "-o", str(tmp_path / "x.mkv"), "--quiet"])
    assert res.exit_code == 1 and "expected a .mp4 or .gif" in res.output
