"""Canny edge maps of grey frames: the ground truth of the CDM evaluation.

The paper compares event edge maps against Canny edges of the grey (APS)
frame, "over various Canny parameters"; the authors' code called MATLAB's
``edge(I, 'Canny', 0.3)``. We run :func:`skimage.feature.canny` over a few
named settings (:data:`CANNY_SETTINGS`), recorded with every result.

MATLAB's ``edge(I, 'Canny', thresh)`` smooths with a Gaussian of
``sigma = sqrt(2)`` and thresholds the gradient magnitude *normalised by its
maximum*: high = ``thresh``, low = ``0.4 * thresh``. skimage thresholds the
absolute Sobel magnitude of the smoothed image, so the ``"matlab"`` mode
computes that magnitude the way skimage does (Gaussian with skimage's
bleed-over correction at the border, Sobel, interior pixels only) and passes
``thresh * max`` and ``0.4 * thresh * max``. The edge maps are not bit-equal to
MATLAB's (different derivative filters), but the thresholds mean the same.

References
----------
.. [1] J. Canny, "A computational approach to edge detection", TPAMI 1986.
.. [2] MATLAB ``edge`` documentation: for 'Canny', "low threshold =
       0.4 * high threshold" and the default sigma is sqrt(2).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy import ndimage as ndi
from skimage.feature import canny
from skimage.filters import gaussian


@dataclass(frozen=True)
class CannySetting:
    """One Canny parameter setting.

    Attributes
    ----------
    name : str
        Label used in results.
    sigma_px : float
        Gaussian smoothing in pixels.
    high : float
        High hysteresis threshold, meaning set by ``mode``.
    low : float
        Low hysteresis threshold, meaning set by ``mode``.
    mode : {"matlab", "quantile", "absolute"}
        ``"matlab"``: fractions of the maximum gradient magnitude;
        ``"quantile"``: quantiles of the gradient magnitude;
        ``"absolute"``: magnitudes for an image scaled to [0, 1].
    """

    name: str
    sigma_px: float
    high: float
    low: float
    mode: str = "matlab"

    def __post_init__(self) -> None:
        if self.mode not in ("matlab", "quantile", "absolute"):
            raise ValueError(f"CannySetting.mode must be matlab, quantile or absolute, got {self.mode!r}")
        if not (self.sigma_px > 0 and math.isfinite(self.sigma_px)):
            raise ValueError(f"CannySetting.sigma_px must be > 0, got {self.sigma_px}")
        if not (0 <= self.low <= self.high):
            raise ValueError(f"CannySetting: need 0 <= low <= high, got low={self.low}, high={self.high}")
        if self.mode in ("matlab", "quantile") and self.high > 1:
            raise ValueError(f"CannySetting.high must be <= 1 in mode {self.mode!r}, got {self.high}")

    def as_dict(self) -> dict:
        return asdict(self)


#: The settings used by the experiments; the first is the paper's (MATLAB ``edge(I,'Canny',0.3)``).
CANNY_SETTINGS = (
    CannySetting("matlab_0.3", sigma_px=math.sqrt(2.0), high=0.3, low=0.12, mode="matlab"),
    CannySetting("matlab_0.2", sigma_px=math.sqrt(2.0), high=0.2, low=0.08, mode="matlab"),
    CannySetting("sigma1_q90", sigma_px=1.0, high=0.9, low=0.8, mode="quantile"),
)


def _as_unit_float(image) -> np.ndarray:
    image = np.asarray(image)
    if image.ndim != 2:
        raise ValueError(f"canny_edges: image must be 2-D grey, got shape {image.shape}")
    if image.dtype == bool or image.dtype.kind not in "uif":
        raise TypeError(f"canny_edges: image must be a numeric grey image, got dtype {image.dtype}")
    if image.dtype.kind in "ui":
        return image.astype(np.float64) / float(np.iinfo(image.dtype).max)
    out = image.astype(np.float64)
    if not np.all(np.isfinite(out)):
        raise ValueError("canny_edges: image has non-finite values")
    return out


def gradient_magnitude(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """Sobel magnitude of the Gaussian-smoothed image as skimage's canny computes it.

    Border pixels (where canny never marks edges) are set to 0.
    """
    img = _as_unit_float(image)
    if img.size == 0:
        return np.zeros(img.shape)
    smoothed = gaussian(img, sigma=sigma_px, mode="constant", cval=0.0, preserve_range=True)
    bleed = gaussian(np.ones_like(img), sigma=sigma_px, mode="constant", cval=0.0, preserve_range=True)
    smoothed = smoothed / (bleed + np.finfo(np.float64).eps)
    mag = np.hypot(ndi.sobel(smoothed, axis=0), ndi.sobel(smoothed, axis=1))
    mag[0, :] = mag[-1, :] = 0
    mag[:, 0] = mag[:, -1] = 0
    return mag


def canny_edges(image, setting: CannySetting = CANNY_SETTINGS[0]) -> np.ndarray:
    """Canny edge map of one grey frame.

    Parameters
    ----------
    image : array_like, shape (H, W)
        Grey image: unsigned integers (scaled by their maximum) or floats in [0, 1].
    setting : CannySetting
        Parameters; default the paper's MATLAB ``edge(I, 'Canny', 0.3)`` equivalent.

    Returns
    -------
    numpy.ndarray of bool, shape (H, W)
    """
    if not isinstance(setting, CannySetting):
        raise TypeError(f"canny_edges: setting must be a CannySetting, got {type(setting).__name__}")
    img = _as_unit_float(image)
    if img.size == 0:  # an empty frame has no edges (skimage would fail on it)
        return np.zeros(img.shape, dtype=bool)
    if setting.mode == "quantile":
        return canny(img, sigma=setting.sigma_px, low_threshold=setting.low,
                     high_threshold=setting.high, use_quantiles=True)
    if setting.mode == "absolute":
        return canny(img, sigma=setting.sigma_px, low_threshold=setting.low, high_threshold=setting.high)
    peak = float(gradient_magnitude(img, setting.sigma_px).max())
    if peak <= 1e-9:
        # a flat image (up to round-off) has no edges; thresholds relative to
        # a round-off maximum would mark noise
        return np.zeros(img.shape, dtype=bool)
    return canny(img, sigma=setting.sigma_px, low_threshold=setting.low * peak,
                 high_threshold=setting.high * peak)
