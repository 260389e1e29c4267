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
    Edge maps of the compared methods (proposed, Mueggler, 1 ms, 30 ms, count)
    and the diagnostic variant (Mueggler with a shifted time origin).
``frame_eval``
    Canny references of frames and CDM tables per frame.
``exp_ransac``, ``exp_lifetime``, ``exp_similarity``, ``exp_qualitative``, ``exp_real``
    The experiments (paper figs. 7, 4-5, 9, 1/8, real frames).
``verdicts``, ``report``, ``paper``
    Claims checked from the numbers, the HTML report, the runner.
``cli``
    ``evedge bench ...`` and ``evedge demo``.
"""
