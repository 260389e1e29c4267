"""evedge.bench: metrics, the paper's experiments and the report.

Modules (imported on use; nothing heavy at import time):

``cdm``
    Closest Distance Metric between edge maps (optimal one-to-one matching).
``canny``
    Canny ground truth over named parameter settings.
``stats``
    F-measure, relative errors, robust histogram peaks (plain and shoulder-aware),
    robust spread of log lifetimes.
``regions``
    Speed bands of the stripes recordings, found without a lifetime estimator.
``methods``
    The compared methods (registered methods under a display policy: proposed,
    Mueggler, 1 ms, 30 ms, count, plug-ins) and their edge maps.
``metrics``
    Registered metrics (lifetime error, normal-flow error, noise filter, CDM) -> result rows.
``results``
    The long results table (CSV + columnar HDF5), the leaderboard.
``grade``
    ``evedge grade``: any method's output against a dataset's truth.
``claims``
    The paper's claims as declarative rules over the results table.
``frame_eval``
    Canny references of frames and CDM tables per frame.
``exp_ransac``, ``exp_lifetime``, ``exp_similarity``, ``exp_qualitative``, ``exp_real``
    The experiments (paper figs. 7, 4-5, 9, 1/8, real frames).
``verdicts``, ``report``, ``report_render``, ``paper``
    Detailed checks of the claims, the HTML report (Jinja2 templates in ``templates/``),
    the runner and its experiment registry.
``cli``
    ``evedge bench ...`` and ``evedge demo``.
"""
