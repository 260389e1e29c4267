"""matplotlib without a display (Agg), imported only when a figure is drawn."""

from __future__ import annotations


def pyplot():
    """Return ``matplotlib.pyplot`` with the non-interactive Agg backend."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt
