"""``evedge simulate``: simulate a scene file, or a user's video or frames, and write the recording."""

from __future__ import annotations

from pathlib import Path

import click


def _check_output(output: Path, fmt: str) -> None:
    # refuse an unwritable output before a simulation that may take minutes
    if fmt == "h5" and output.is_dir():
        raise click.BadParameter(f"{output} is an existing folder; --format h5 writes a file",
                                 param_hint="'-o' / '--output'")
    if fmt == "h5" and not output.parent.is_dir():
        raise click.BadParameter(f"folder {output.parent} of {output} does not exist",
                                 param_hint="'-o' / '--output'")
    if fmt == "ecd" and output.exists() and not output.is_dir():
        raise click.BadParameter(f"{output} is an existing file; --format ecd writes a folder",
                                 param_hint="'-o' / '--output'")
    for name in ("events.txt", "images.txt", "images") if fmt == "ecd" else ():
        if (output / name).is_symlink():  # before the run: write_ecd refuses it too
            raise click.BadParameter(f"{output / name} is a symbolic link; it is not written through",
                                     param_hint="'-o' / '--output'")


@click.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path), required=False)
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=Path),
              help="Output: an .h5 file (--format h5) or a folder (--format ecd).")
@click.option("--seed", type=click.IntRange(min=0), default=None, help="Override the scene's seed (frames: 0).")
@click.option("--duration", "duration_s", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Override the scene's duration (seconds).")
@click.option("--frame-rate", "frame_rate_hz", type=click.FloatRange(min=0), default=None,
              help="Rate of clean frames and edge maps (Hz; default: the scene's, 0 for none).")
@click.option("--format", "fmt", type=click.Choice(["h5", "ecd"]), default="h5", show_default=True,
              help="h5: events, truth, frames, edges, scene and versions (evedge HDF5); "
                   "ecd: Event Camera Dataset text folder (events and frames only).")
@click.option("--sensor", "sensor", default=None, metavar="PRESET",
              help="A sensor preset (dvs128, davis240, davis346, dvxplorer, gen3, gen4; see evedge.sensors). "
                   "Scenes: rendered at its resolution (coordinates stay in pixels). Video/frames: resized to "
                   "it, with its thresholds and refractory period.")
@click.option("--video", "video", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Convert this video file (OpenCV) instead of a scene.")
@click.option("--frames", "frames_dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Convert this folder of images (sorted by name; timestamps.txt used when present).")
@click.option("--timestamps", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Video/frames: frame times, one per line in seconds (default: the container's, or "
                   "timestamps.txt).")
@click.option("--rate", "rate_hz", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Video/frames: frame k at k / RATE seconds.")
@click.option("--log-input", is_flag=True, help="Video/frames: the frames hold log intensity already.")
@click.option("--upsample", type=click.IntRange(1, 1000), default=1, show_default=True,
              help="Video/frames: samples per frame interval.")
@click.option("--interpolation", type=click.Choice(["log", "flow"]), default="log", show_default=True,
              help="Video/frames: sub-frames by log-intensity interpolation or by Farneback optical flow.")
@click.option("--contrast", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Video/frames: ON and OFF thresholds (log units; default 0.2 or the --sensor preset's).")
@click.option("--contrast-sigma", type=click.FloatRange(min=0), default=None,
              help="Video/frames: per-pixel threshold mismatch (std, log units).")
@click.option("--refractory-us", type=click.FloatRange(min=0), default=None, help="Video/frames: refractory period.")
@click.option("--noise-rate-hz", type=click.FloatRange(min=0, max=1e6), default=None,
              help="Video/frames: background activity per pixel.")
@click.option("--overwrite", is_flag=True, help="Replace an existing OUTPUT.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def simulate(scene: Path | None, output: Path, seed, duration_s, frame_rate_hz, fmt: str, sensor, video, frames_dir,
             timestamps, rate_hz, log_input, upsample, interpolation, contrast, contrast_sigma, refractory_us,
             noise_rate_hz, overwrite: bool, quiet: bool) -> None:
    """Simulate the scene file SCENE (TOML, see sim/SCENES.md), or --video FILE / --frames DIR, into OUTPUT.

    The output is written whole (a temporary file or folder, then renamed); an
    existing OUTPUT is replaced only with --overwrite.
    """
    from evedge._output import OutputExistsError, check_output
    from evedge.io import write_ecd, write_recording

    inputs = [x for x in (scene, video, frames_dir) if x is not None]
    if len(inputs) != 1:
        raise click.UsageError("give exactly one of SCENE, --video FILE or --frames DIR")
    model = None
    if sensor is not None:
        from evedge.sensors import SENSOR_MODELS
        if sensor.strip().lower() not in SENSOR_MODELS:
            raise click.BadParameter(f"unknown sensor preset {sensor!r}; known: {sorted(SENSOR_MODELS)}",
                                     param_hint="'--sensor'")
        model = SENSOR_MODELS[sensor.strip().lower()]
    frame_opts = dict(timestamps=timestamps, rate_hz=rate_hz, contrast=contrast, contrast_sigma=contrast_sigma,
                      refractory_us=refractory_us, noise_rate_hz=noise_rate_hz)
    _check_output(output, fmt)

    def replacing() -> bool:
        """After the usage checks, before any work: refuse or announce replacing OUTPUT."""
        try:
            return check_output(output, overwrite=overwrite)
        except OutputExistsError as err:
            raise click.ClickException(str(err)) from None
    if scene is not None:
        used = [("--rate" if k == "rate_hz" else "--" + k.replace("_", "-"))
                for k, v in frame_opts.items() if v is not None]
        used += (["--log-input"] if log_input else []) + (["--upsample"] if upsample != 1 else [])
        if used:
            raise click.UsageError(f"{used[0]} applies to --video/--frames only "
                                   "(a scene sets its pixel model in its [events] table)")
        from .scene import SceneError, load_scene, with_sensor
        from .simulate import simulate as run
        replaces = replacing()
        try:
            parsed = load_scene(scene) if sensor is None else with_sensor(load_scene(scene), sensor)
            rec = run(parsed, seed=seed, duration_s=duration_s, frame_rate_hz=frame_rate_hz, progress=not quiet)
            path = write_recording(output, rec) if fmt == "h5" else write_ecd(output, rec)
        except (SceneError, ValueError, TypeError, OSError, MemoryError) as err:
            raise click.ClickException(str(err) or type(err).__name__) from None
    else:
        for name, value in (("--duration", duration_s), ("--frame-rate", frame_rate_hz)):
            if value is not None:
                raise click.UsageError(f"{name} applies to scenes only")
        replaces = replacing()
        from dataclasses import replace

        from .converter import ConverterParams
        from .frames import FramesError, open_frames_folder, open_video, simulate_frames
        params = ConverterParams(**(model.event_params if model else {}))
        changes = {k: float(v) for k, v in (("contrast_sigma", contrast_sigma), ("refractory_us", refractory_us),
                                            ("noise_rate_hz", noise_rate_hz)) if v is not None}
        if contrast is not None:
            changes.update(contrast_pos=float(contrast), contrast_neg=float(contrast))
        try:
            params = replace(params, **changes)
            opener = open_video if video is not None else open_frames_folder
            source = opener(video if video is not None else frames_dir, timestamps=timestamps, rate_hz=rate_hz)
            rec = simulate_frames(source, params, seed=seed or 0, log_input=log_input, upsample=upsample,
                                  interpolation=interpolation, progress=not quiet,
                                  resize=(model.width, model.height) if model else None)
            path = write_recording(output, rec) if fmt == "h5" else write_ecd(output, rec)
        except (FramesError, ValueError, TypeError, OSError, MemoryError) as err:
            raise click.ClickException(str(err) or type(err).__name__) from None
    if replaces:
        click.echo(f"replaced the earlier output {output}", err=True)
    md = rec.metadata
    click.echo(f"{path}: {rec.events.shape[0]} events ({md['n_signal']} signal, {md['n_noise']} noise), "
               f"{md['duration_s']} s, {rec.sensor_size.width}x{rec.sensor_size.height}, "
               f"{0 if rec.frames is None else len(rec.frames)} frames, seed {md['seed']}")
