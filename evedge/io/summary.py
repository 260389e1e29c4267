"""Facts about a recording: counts, duration, rates, polarity balance."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..events import Recording

PEAK_WINDOW_US = 10_000


def peak_count(t_us: np.ndarray, window_us: int) -> int:
    """Largest number of events in any window ``[t_i, t_i + window_us)`` (sorted ``t_us``)."""
    if t_us.size == 0:
        return 0
    ends = np.searchsorted(t_us, t_us + window_us, side="left")
    return int((ends - np.arange(t_us.size)).max())


def summarize(recording: Recording) -> dict[str, Any]:
    """Summarise a recording as a JSON-serialisable dict.

    Parameters
    ----------
    recording : Recording
        Events sorted by time (as every reader returns them).

    Returns
    -------
    dict
        ``source``, ``format``, ``events`` (count), ``t_first_us``, ``t_last_us``,
        ``duration_s``, ``sensor_width``, ``sensor_height``, ``sensor_size_from``,
        ``mean_rate_ev_s`` (events / duration, None under two distinct times),
        ``peak_rate_10ms_ev_s`` (most events in a sliding 10 ms window starting
        at an event, divided by 10 ms), ``on_count``, ``off_count``,
        ``on_fraction`` (None without events), ``frames``, ``edges`` (counts)
        and ``truth_fields`` (names, empty without truth).
    """
    if not isinstance(recording, Recording):
        raise TypeError(f"summarize: expected a Recording, got {type(recording).__name__}")
    ev = recording.events
    n = int(ev.size)
    t = ev["t"]
    t_first = int(t[0]) if n else None
    t_last = int(t[-1]) if n else None
    duration_s = (t_last - t_first) / 1e6 if n else 0.0
    on = int(np.count_nonzero(ev["p"]))
    meta = recording.metadata
    return {
        "source": meta.get("source"),
        "format": meta.get("format"),
        "events": n,
        "t_first_us": t_first,
        "t_last_us": t_last,
        "duration_s": duration_s,
        "sensor_width": recording.sensor_size.width,
        "sensor_height": recording.sensor_size.height,
        "sensor_size_from": meta.get("sensor_size_from"),
        "mean_rate_ev_s": n / duration_s if duration_s > 0 else None,
        "peak_rate_10ms_ev_s": peak_count(t, PEAK_WINDOW_US) / (PEAK_WINDOW_US / 1e6),
        "on_count": on,
        "off_count": n - on,
        "on_fraction": on / n if n else None,
        "frames": len(recording.frames) if recording.frames is not None else 0,
        "edges": len(recording.edges) if recording.edges is not None else 0,
        "truth_fields": list(recording.truth.dtype.names) if recording.truth is not None else [],
        "calibration": recording.calibration.as_list() if recording.calibration is not None else None,
        **({"detection": {k: meta.get(k) for k in ("method", "method_display_name", "kind", "display", "params",
                                                   "filter", "filter_params", "detection_source", "versions")}}
           if meta.get("format") == "evedge-detection" else {}),
    }


def format_summary(info: dict[str, Any]) -> str:
    """Render :func:`summarize`'s dict as aligned text lines."""

    def rate(value) -> str:
        return "n/a" if value is None else f"{value:,.0f} ev/s"

    has_events = bool(info["events"])
    no_events = "n/a (no events)"
    lines = [
        ("file", f"{info['source']} ({info['format']})"),
        ("events", f"{info['events']:,}"),
        ("duration",
         f"{info['duration_s']:.6f} s (t = {info['t_first_us'] / 1e6:.6f} .. {info['t_last_us'] / 1e6:.6f} s)"
         if has_events else no_events),
        ("sensor", f"{info['sensor_width']}x{info['sensor_height']} (from {info['sensor_size_from']})"),
        ("mean rate", rate(info["mean_rate_ev_s"])),
        ("peak rate", rate(info["peak_rate_10ms_ev_s"] if has_events else None) + " (10 ms window)"),
        ("polarity",
         f"ON {100 * info['on_fraction']:.1f} % ({info['on_count']:,} ON / {info['off_count']:,} OFF)"
         if has_events else no_events),
        ("frames", str(info["frames"])),
        ("edge maps", str(info["edges"])),
        ("truth", ", ".join(info["truth_fields"]) or "none"),
    ]
    det = info.get("detection")
    if det:  # an evedge detect output: what made it
        src = det.get("detection_source") or {}
        lines += [
            ("method", f"{det['method']} ({det.get('method_display_name')}, {det.get('kind')})"
             + (f", display {det['display']}" if det.get("display") else "")),
            ("params", ", ".join(f"{k}={v}" for k, v in (det.get("params") or {}).items()) or "none"),
            ("filter", f"{det['filter']}: " + ", ".join(f"{k}={v}" for k, v in (det.get("filter_params") or {}).items())
             if det.get("filter") else "none"),
            ("source", f"{src.get('path')} (sha256 {str(src.get('sha256'))[:16]}...)"),
            ("versions", ", ".join(f"{k} {v}" for k, v in (det.get("versions") or {}).items())),
        ]
    if info.get("calibration") is not None:
        fx, fy, cx, cy, *dist = info["calibration"]
        lines.append(("calibration", f"fx {fx:.3f} fy {fy:.3f} cx {cx:.3f} cy {cy:.3f}, "
                                     f"k1 k2 p1 p2 k3 = {' '.join(f'{d:.4g}' for d in dist)}"))
    width = max(len(k) for k, _ in lines)
    return "\n".join(f"{k:<{width}}  {v}" for k, v in lines)
