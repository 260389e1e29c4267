"""``evedge simulate``: simulate a scene file and write the recording."""

from __future__ import annotations

from pathlib import Path

import click


@click.command()
@click.argument("scene", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--output", "output", required=True, type=click.Path(path_type=Path),
              help="Output: an .h5 file (--format h5) or a folder (--format ecd).")
@click.option("--seed", type=click.IntRange(min=0), default=None, help="Override the scene's seed.")
@click.option("--duration", "duration_s", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Override the scene's duration (seconds).")
@click.option("--frame-rate", "frame_rate_hz", type=click.FloatRange(min=0), default=None,
              help="Rate of clean frames and edge maps (Hz; default: the scene's, 0 for none).")
@click.option("--format", "fmt", type=click.Choice(["h5", "ecd"]), default="h5", show_default=True,
              help="h5: events, truth, frames, edges, scene and versions (evedge HDF5); "
                   "ecd: Event Camera Dataset text folder (events and frames only).")
@click.option("--sensor", "sensor", default=None, metavar="PRESET",
              help="Render the scene on this sensor preset instead of its own (dvs128, davis240, davis346, "
                   "dvxplorer, gen3, gen4; see evedge.sensors); scene coordinates stay in pixels.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def simulate(scene: Path, output: Path, seed, duration_s, frame_rate_hz, fmt: str, sensor, quiet: bool) -> None:
    """Simulate the scene file SCENE (TOML, see sim/SCENES.md) and write it to OUTPUT."""
    from .scene import SceneError, load_scene, with_sensor
    from .simulate import simulate as run

    from evedge.io import write_ecd, write_recording

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
    if sensor is not None:
        from evedge.sensors import SENSOR_MODELS
        if sensor.strip().lower() not in SENSOR_MODELS:
            raise click.BadParameter(f"unknown sensor preset {sensor!r}; known: {sorted(SENSOR_MODELS)}",
                                     param_hint="'--sensor'")
    try:
        parsed = load_scene(scene) if sensor is None else with_sensor(load_scene(scene), sensor)
        rec = run(parsed, seed=seed, duration_s=duration_s, frame_rate_hz=frame_rate_hz, progress=not quiet)
        path = write_recording(output, rec) if fmt == "h5" else write_ecd(output, rec)
    except (SceneError, ValueError, TypeError, OSError, MemoryError) as err:
        raise click.ClickException(str(err) or type(err).__name__) from None
    md = rec.metadata
    click.echo(f"{path}: {rec.events.shape[0]} events ({md['n_signal']} signal, {md['n_noise']} noise), "
               f"{md['duration_s']} s, {rec.sensor_size.width}x{rec.sensor_size.height}, "
               f"{0 if rec.frames is None else len(rec.frames)} frames, seed {md['seed']}")
