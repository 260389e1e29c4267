"""CDM of every method's edge map against reference maps, frame by frame.

Shared by the similarity-over-time experiment (simulated, Canny and exact
truths) and the real-frames experiment (Canny only).
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from .canny import CANNY_SETTINGS, canny_edges
from .cdm import cdm


def canny_references(images, settings=CANNY_SETTINGS) -> dict[str, np.ndarray]:
    """Canny maps of each grey frame for each setting: name -> (n, H, W) bool."""
    images = np.asarray(images)
    return {f"canny_{s.name}": np.stack([canny_edges(im, s) for im in images]) if len(images)
            else np.zeros((0,) + images.shape[1:], bool) for s in settings}


def cdm_table(maps: dict[str, np.ndarray], references: dict[str, np.ndarray], *, progress: bool = True,
              desc: str = "CDM") -> dict[str, dict[str, np.ndarray]]:
    """CDM of each method's map against each reference, per frame.

    Parameters
    ----------
    maps : dict
        method -> (n, H, W) bool.
    references : dict
        reference name -> (n, H, W) bool (same frames).
    progress : bool
        Show a tqdm progress bar (stderr).
    desc : str
        Label of the progress bar.

    Returns
    -------
    dict
        reference -> method -> (n,) float CDM.
    """
    n = None
    for label, stack in list(maps.items()) + list(references.items()):
        if n is None:
            n = stack.shape[0]
        elif stack.shape[0] != n:
            raise ValueError(f"cdm_table: {label} has {stack.shape[0]} frames, expected {n}")
    total = len(maps) * len(references) * (n or 0)
    out: dict[str, dict[str, np.ndarray]] = {}
    with tqdm(total=total, desc=desc, unit="map", disable=not progress, leave=False) as bar:
        for ref_name, ref in references.items():
            out[ref_name] = {}
            for method, stack in maps.items():
                vals = np.empty(n or 0)
                for i in range(n or 0):
                    vals[i] = cdm(stack[i], ref[i])
                    bar.update(1)
                out[ref_name][method] = vals
    return out


def summarise(values) -> dict:
    """Median, quartiles, mean and count of finite values (NaN when empty)."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return {"median": float("nan"), "q1": float("nan"), "q3": float("nan"), "mean": float("nan"), "n": 0}
    q1, med, q3 = np.percentile(v, [25, 50, 75])
    return {"median": float(med), "q1": float(q1), "q3": float(q3), "mean": float(v.mean()), "n": int(v.size)}
