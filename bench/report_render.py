"""Rendering only: Jinja2 templates (``bench/templates/``) fed with numbers computed elsewhere.

Nothing here computes a result: the leaderboard and the claim lines come from
:mod:`evedge.bench.results` and :mod:`evedge.bench.verdicts`; this module
formats numbers, inlines figures and fills the templates (autoescaped).
"""

from __future__ import annotations

import base64
import math
from pathlib import Path

__all__ = ["environment", "render_grade"]

CSS = """
body{font-family:system-ui,sans-serif;max-width:1200px;margin:1em auto;padding:0 1em;color:#222}
h1{font-size:1.5em} h2{border-bottom:1px solid #ccc;margin-top:1.6em} h3{font-size:1.05em}
table{border-collapse:collapse;margin:0.5em 0;font-size:0.85em}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right} th{background:#f3f3f3}
td.l,th.l{text-align:left}
.holds{background:#dff5df} .fails{background:#fadddd} .nc{background:#eee}
img{max-width:100%;border:1px solid #eee;margin:0.3em 0}
pre{background:#f7f7f7;padding:0.5em;font-size:0.8em;overflow-x:auto}
.small{font-size:0.85em;color:#555}
.row{display:flex;gap:0.5em;align-items:flex-start} .row>div{flex:1 1 0;min-width:0}
"""


def _num(x, nd: int = 2) -> str:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return "n/a" if x is None else str(x)
    return "n/a" if not math.isfinite(v) else f"{v:.{nd}f}"


def _img(path) -> str:
    from markupsafe import Markup, escape

    p = Path(path)
    if not p.exists():
        return Markup(f"<p class='small'>(figure missing: {escape(p.name)})</p>")
    data = base64.b64encode(p.read_bytes()).decode("ascii")
    return Markup(f"<img alt='{escape(p.name)}' src='data:image/png;base64,{data}'>")


def environment():
    """The Jinja2 environment of the bench's templates (autoescape on, undefined names are errors)."""
    import jinja2

    from .methods import label

    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(Path(__file__).with_name("templates"))),
                             autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    env.filters.update(num=_num, img=_img, label=label)
    env.globals["css"] = CSS
    return env


def render_grade(table, info: dict, figures: list) -> str:
    """``evedge grade``'s report: one table per metric family, the figure, the inputs."""
    summary = [r for r in table.rows if not r["section"].startswith("frame_")]
    frames = [r for r in table.rows if r["section"].startswith("frame_")]
    return environment().get_template("grade.html.j2").render(
        info=info, summary=summary, frames=frames, figures=figures)
