"""matplotlib without a display (Agg), imported only when a figure is drawn."""

from __future__ import annotations


def pyplot():
    """Return ``matplotlib.pyplot`` with the non-interactive Agg backend."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


#: One colour per method, as in the paper's figure 8 (proposed magenta, Mueggler yellow-ish,
#: 30 ms cyan, 1 ms green); the event count is grey.
METHOD_COLOURS = {
    "proposed": "#d62ad6",
    "mueggler": "#c9a400",
    "acc_1ms": "#2ca02c",
    "acc_30ms": "#17becf",
    "acc_count": "#7f7f7f",
}
