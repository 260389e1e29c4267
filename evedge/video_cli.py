"""``evedge render``: a video (MP4 or GIF) of the events of a recording, or of its edge maps."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from ._cli_options import sensor_option
from .events import SensorSize


def _frame_times(t0: int, t1: int, fps: float) -> np.ndarray:
    step = 1e6 / fps
    return np.rint(np.arange(t0 + step, t1 + step / 2, step)).astype(np.int64)


@click.command()
@click.argument("source", type=click.Path(exists=True, path_type=str))
@click.option("-o", "--out", "out", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Output video: .mp4 (OpenCV) or .gif (Pillow).")
@click.option("--fps", type=click.FloatRange(min=0.01, max=10_000), default=30.0, show_default=True,
              help="Frames per second of recording time.")
@click.option("--at-frames", is_flag=True, help="One video frame at each grey frame of the recording (instead of --fps).")
@click.option("--window-ms", type=click.FloatRange(min=0.001), default=10.0, show_default=True,
              help="Events shown in each frame: those of this window before its time.")
@click.option("--edges", "show_edges", is_flag=True,
              help="Draw the recording's edge maps (an evedge detect output, or simulated truth) instead of events.")
@click.option("--scale", type=click.IntRange(1, 64), default=None, help="Integer upscaling (default: at least 480 rows).")
@click.option("--play-fps", type=click.FloatRange(min=0.1, max=1000), default=None,
              help="Playback rate of the video (default: --fps, at most 60: real time when it can be).")
@sensor_option()
@click.option("--sort", is_flag=True, help="Sort events by time (stable) if the file is unsorted.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def render(source, out, fps, at_frames, window_ms, show_edges, scale, play_fps, sensor: SensorSize | None, sort, quiet):
    """Render SOURCE (any event file evedge reads) as a video OUT of event frames, coloured by polarity
    (ON red, OFF blue) over the grey frames when there are any, with a time caption."""
    from .io import read_events
    from .video import edge_video_frames, event_video_frames, write_video

    try:
        rec = read_events(source, sensor_size=sensor, sort=sort)
    except (ValueError, TypeError, OSError) as err:
        raise click.ClickException(str(err)) from None
    ev = rec.events
    if show_edges:
        if rec.edges is None or not len(rec.edges):
            raise click.BadParameter(f"{source} holds no edge maps", param_hint="'--edges'")
        frames = edge_video_frames(rec.edges, grey=rec.frames, colour="mono", scale=scale)
        n = len(rec.edges)
    else:
        if at_frames:
            if rec.frames is None or not len(rec.frames):
                raise click.BadParameter(f"{source} has no grey frames", param_hint="'--at-frames'")
            times = rec.frames.t_us
        elif ev.size:
            times = _frame_times(int(ev["t"][0]), int(ev["t"][-1]), fps)
        else:
            times = np.empty(0, np.int64)
        if times.size == 0:
            raise click.ClickException(f"{source}: no frame to render (no events, or they span less than one "
                                       f"frame period at --fps {fps:g})")
        frames = event_video_frames(ev, rec.sensor_size, times, window_us=max(1, int(round(window_ms * 1000))),
                                    grey=rec.frames, scale=scale)
        n = int(times.size)
    rate = play_fps or min(fps, 60.0)
    try:
        write_video(out, frames, fps=rate, n_frames=n, quiet=quiet)
    except (ValueError, OSError) as err:
        raise click.ClickException(str(err)) from None
    click.echo(f"{out}: {n} frames at {rate:g} fps")
