"""evedge: edge detection for event cameras by lifetime estimation, and its testbench.

Sub-packages
------------
evedge.io        readers and writers of event files (one event type: :mod:`evedge.events`)
evedge.sim       scenes, renderers and an ESIM-style event simulator with ground truth
evedge.detector  the BMVC 2019 intra-pixel-area lifetime detector and its baselines
evedge.bench     metrics (CDM), Canny truth, the paper's experiments and reports
"""

__version__ = "0.1.0"
