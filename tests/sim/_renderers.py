"""Stub renderers of the converter tests: a still grey image and an exact log-intensity ramp."""

import math

import numpy as np


class StillRenderer:
    """``width x height`` pixels of grey 0.5 without motion or edges (subclasses change the image)."""

    width = height = 1

    def intensity(self, t_s):
        return np.full((self.height, self.width), 0.5)

    def flow(self, t_s):
        return np.zeros((2, self.height, self.width))

    def edges(self, t_s):
        return np.zeros((self.height, self.width), bool)

    def max_speed_px_s(self, t0_s, t1_s):
        return 0.0

    def close(self):
        pass


class RampRenderer(StillRenderer):
    """Pixels whose log intensity is the exact ramp L(t) = L0 + k t (so I = exp(L) - eps)."""

    def __init__(self, l0, k, eps=1e-3):
        self.l0, self.k, self.eps = l0, k, eps

    def intensity(self, t_s):
        return np.full((self.height, self.width), math.exp(self.l0 + self.k * t_s) - self.eps)
