"""The benchmarks' ``--preset`` / ``--intra key=value`` options: which :class:`IntraParams` a run measures."""

from __future__ import annotations

import dataclasses

from evedge.detector.intra import IntraParams, noise_params, robust_params


#: --preset: where the intra parameters start (``--intra`` changes fields on top).
PRESETS = {"defaults": IntraParams, "robust": robust_params, "noise": noise_params}


def _parse_intra(items, base: IntraParams | None = None) -> IntraParams:
    base = IntraParams() if base is None else base
    fields = {f.name: f for f in dataclasses.fields(IntraParams)}
    kw = {}
    for item in items:
        key, _, value = item.partition("=")
        if key not in fields:
            raise SystemExit(f"--intra: unknown IntraParams field {key!r} (fields: {', '.join(fields)})")
        default = getattr(IntraParams(), key)
        try:
            if isinstance(default, bool):
                if value.lower() not in ("1", "true", "yes", "on", "0", "false", "no", "off"):
                    raise ValueError(f"expected true/false, got {value!r}")
                kw[key] = value.lower() in ("1", "true", "yes", "on")
            elif isinstance(default, (int, float)):
                kw[key] = type(default)(float(value))
            else:
                kw[key] = value
        except ValueError as err:
            raise SystemExit(f"--intra {key}: {err}") from None
    try:
        return dataclasses.replace(base, **kw)
    except (TypeError, ValueError) as err:
        raise SystemExit(f"--intra: {err}") from None
