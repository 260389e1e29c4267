"""README pictures of the simulator: a rendered frame, the events of a short window, and the
ground-truth lifetime coloured on those events.

Run: ``.venv/bin/python docs/make_sim_figures.py``; writes ``docs/img/sim_*.png``.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from evedge.sim import load_scene, simulate  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "img"


def _save(fig, name: str) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=OUT, prefix=f".{name}.", suffix=".png")
    os.close(fd)
    fig.savefig(tmp, dpi=110, bbox_inches="tight")
    plt.close(fig)
    os.replace(tmp, OUT / name)
    print(OUT / name)


def _window(rec, t0_us: int, t1_us: int):
    ev, tr = rec.events, rec.truth
    sel = (ev["t"] >= t0_us) & (ev["t"] < t1_us)
    return ev[sel], tr[sel]


def _scene_figures(name: str, t_ms: float, window_ms: float) -> None:
    scene = load_scene(ROOT / "scenes" / f"{name}.toml")
    rec = simulate(scene, duration_s=(t_ms + window_ms) / 1e3 + 0.01, frame_rate_hz=1e3 / t_ms, progress=False)
    k = int(np.argmin(np.abs(rec.frames.t_us - t_ms * 1e3)))
    frame, edges = rec.frames.images[k], rec.edges.images[k]
    ev, tr = _window(rec, int((t_ms - window_ms) * 1e3), int(t_ms * 1e3))
    h, w = frame.shape

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6))
    axes[0].imshow(frame, cmap="gray", vmin=0, vmax=1)
    axes[0].set_title(f"{name}: clean frame at t = {t_ms:g} ms")
    axes[1].imshow(edges, cmap="gray_r")
    axes[1].set_title("exact edge map (boundary crosses pixel)")
    for a in axes:
        a.set_xticks([]), a.set_yticks([])
    _save(fig, f"sim_{name}_frame.png")

    fig, ax = plt.subplots(figsize=(4.8, 3.6 * h / max(h, w) + 0.4))
    img = np.full((h, w, 3), 1.0)
    img[ev["y"][ev["p"]], ev["x"][ev["p"]]] = (0.85, 0.1, 0.1)
    img[ev["y"][~ev["p"]], ev["x"][~ev["p"]]] = (0.1, 0.2, 0.85)
    ax.imshow(img)
    ax.set_title(f"events {t_ms - window_ms:g}-{t_ms:g} ms (red ON, blue OFF)", fontsize=9)
    ax.set_xticks([]), ax.set_yticks([])
    _save(fig, f"sim_{name}_events.png")

    fig, ax = plt.subplots(figsize=(5.6, 3.6 * h / max(h, w) + 0.4))
    sig = tr["is_signal"] & np.isfinite(tr["lifetime_us"])
    order = np.argsort(ev["t"][sig])
    sc = ax.scatter(ev["x"][sig][order], ev["y"][sig][order], c=tr["lifetime_us"][sig][order] / 1e3, s=3,
                    cmap="viridis", norm=matplotlib.colors.LogNorm())
    ax.set_xlim(-0.5, w - 0.5), ax.set_ylim(h - 0.5, -0.5), ax.set_aspect("equal")
    ax.set_xticks([]), ax.set_yticks([])
    ax.set_title("ground-truth lifetime of these events", fontsize=9)
    fig.colorbar(sc, ax=ax, label="lifetime (ms)")
    _save(fig, f"sim_{name}_lifetime.png")


def _lifetime_histogram() -> None:
    rec = simulate(load_scene(ROOT / "scenes" / "stripes.toml"), duration_s=0.4, frame_rate_hz=0, progress=False)
    lt = rec.truth["lifetime_us"][rec.truth["is_signal"]]
    fig, ax = plt.subplots(figsize=(5, 3))
    ax.hist(lt / 1e3, bins=np.linspace(0, 25, 101))
    ax.set_xlabel("ground-truth lifetime (ms)")
    ax.set_ylabel("events")
    ax.set_title("stripes: two speed regions, two lifetimes", fontsize=9)
    _save(fig, "sim_stripes_lifetime_hist.png")


def main() -> None:
    _scene_figures("shapes_translation", 300.0, 20.0)
    _scene_figures("stripes", 200.0, 20.0)
    _lifetime_histogram()


if __name__ == "__main__":
    main()
