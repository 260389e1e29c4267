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

Two backends (``backend=``): ``"skimage"`` (default, the reference) and
``"opencv"`` (``opencv-python-headless``): the same smoothing (Gaussian of the
same radius, ``truncate = 4``, with skimage's bleed-over correction), the same
3x3 Sobel gradients and the same thresholds, then OpenCV's non-maximum
suppression and hysteresis (``cv2.Canny`` on the gradients quantised to int16,
L2 magnitude). OpenCV's suppression compares a pixel with its two neighbours
along the gradient sector, skimage's with values interpolated along the exact
gradient direction, so a few pixels differ where an edge runs between two
sectors (and on a perfectly symmetric step, where skimage keeps both tied
columns, OpenCV keeps one), and hysteresis can then keep or drop a weak chain.
Stated tolerance, checked by ``tests/bench/test_canny.py`` on simulated
shapes_translation and real slider_depth 240x180 frames, every setting: on
every frame at least 90 % of each map's edge pixels lie within 1 px of an edge
pixel of the other map, and at least 97 % on average over the frames (measured
2026-12-01: worst frame 93.5 %, mean 97.6-99.4 %). Speed on a 240x180 frame
(``benchmarks/bench_cdm.py``, CPU, one core): 2.6-3.0 ms (skimage) against
0.6-0.9 ms (OpenCV) for the MATLAB-style settings.

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


#: Canny implementations: the reference and the fast one.
BACKENDS = ("skimage", "opencv")


def _canny_opencv(img: np.ndarray, setting: CannySetting) -> np.ndarray:
    """:func:`canny_edges` through OpenCV (see the module notes)."""
    import cv2

    radius = int(4.0 * setting.sigma_px + 0.5)  # skimage's gaussian: truncate = 4
    ksize = (2 * radius + 1, 2 * radius + 1)
    smoothed = cv2.GaussianBlur(img, ksize, setting.sigma_px, borderType=cv2.BORDER_CONSTANT)
    bleed = cv2.GaussianBlur(np.ones_like(img), ksize, setting.sigma_px, borderType=cv2.BORDER_CONSTANT)
    smoothed = smoothed / (bleed + np.finfo(np.float64).eps)
    # ndimage.sobel(axis=1) is d/dx: the same 3x3 kernels as cv2.Sobel
    gx = cv2.Sobel(smoothed, cv2.CV_64F, 1, 0, ksize=3, borderType=cv2.BORDER_REFLECT)
    gy = cv2.Sobel(smoothed, cv2.CV_64F, 0, 1, ksize=3, borderType=cv2.BORDER_REFLECT)
    for g in (gx, gy):  # canny never marks the border
        g[0, :] = g[-1, :] = 0
        g[:, 0] = g[:, -1] = 0
    mag = np.hypot(gx, gy)
    peak = float(mag.max())
    if peak <= 1e-9:
        return np.zeros(img.shape, dtype=bool)
    if setting.mode == "quantile":
        low, high = np.quantile(mag, [setting.low, setting.high])
    elif setting.mode == "absolute":
        low, high = setting.low, setting.high
    else:
        low, high = setting.low * peak, setting.high * peak
    scale = 32000.0 / max(float(np.abs(gx).max()), float(np.abs(gy).max()))
    dx = np.rint(gx * scale).astype(np.int16)
    dy = np.rint(gy * scale).astype(np.int16)
    out = cv2.Canny(dx, dy, float(low * scale), float(high * scale), L2gradient=True)
    return out > 0


def canny_edges(image, setting: CannySetting = CANNY_SETTINGS[0], *, backend: str = "skimage") -> np.ndarray:
    """Canny edge map of one grey frame.

    Parameters
    ----------
    image : array_like, shape (H, W)
        Grey image: unsigned integers (scaled by their maximum) or floats in [0, 1].
    setting : CannySetting
        Parameters; default the paper's MATLAB ``edge(I, 'Canny', 0.3)`` equivalent.
    backend : {"skimage", "opencv"}
        The reference (scikit-image) or OpenCV (faster; equal within the
        tolerance stated in the module notes).

    Returns
    -------
    numpy.ndarray of bool, shape (H, W)

    Examples
    --------
    >>> import numpy as np
    >>> img = np.zeros((32, 32)); img[:, 16:] = 1.0
    >>> e = canny_edges(img)
    >>> bool(e[:, 15:17].any(axis=1)[4:-4].all()), int(e[:, :13].sum())
    (True, 0)
    >>> bool(canny_edges(img, backend="opencv")[4:-4, 15].all())  # of the two tied columns, one
    True
    """
    if not isinstance(setting, CannySetting):
        raise TypeError(f"canny_edges: setting must be a CannySetting, got {type(setting).__name__}")
    if backend not in BACKENDS:
        raise ValueError(f"canny_edges: backend must be one of {BACKENDS}, got {backend!r}")
    img = _as_unit_float(image)
    if img.size == 0:  # an empty frame has no edges (skimage would fail on it)
        return np.zeros(img.shape, dtype=bool)
    if backend == "opencv":
        return _canny_opencv(img, setting)
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
