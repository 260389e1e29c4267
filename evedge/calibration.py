"""Pinhole camera calibration with radial-tangential distortion, and undistortion of events and frames.

The model is OpenCV's (and the Event Camera Dataset's ``calib.txt``: ``fx fy
cx cy k1 k2 p1 p2 k3``): a point with normalised ideal coordinates
``(x, y)``, ``r2 = x^2 + y^2``, is seen at

    x_d = x (1 + k1 r2 + k2 r2^2 + k3 r2^3) + 2 p1 x y + p2 (r2 + 2 x^2)
    y_d = y (1 + k1 r2 + k2 r2^2 + k3 r2^3) + p1 (r2 + 2 y^2) + 2 p2 x y

and at pixel ``(fx x_d + cx, fy y_d + cy)``. Undistortion inverts it
through OpenCV (``cv2.undistortPoints`` for events, ``cv2.undistort`` for
frames), keeping the same camera matrix, so the undistorted image has the
sensor's size and focal length.

References
----------
.. [1] OpenCV, "Camera Calibration and 3D Reconstruction" (calib3d), docs.opencv.org.
.. [2] E. Mueggler et al., "The Event-Camera Dataset and Simulator", IJRR 2017 (``calib.txt``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._validate import check_finite, check_positive
from .events import EVENT_DTYPE, Frames, SensorSize, validate_events

__all__ = ["CameraCalibration", "distort_points", "undistort_events", "undistort_frames", "undistortion_map"]


@dataclass(frozen=True)
class CameraCalibration:
    """Intrinsics (pixels) and radial-tangential distortion (dimensionless).

    Attributes
    ----------
    fx_px, fy_px : float
        Focal lengths, > 0.
    cx_px, cy_px : float
        Principal point.
    k1, k2, p1, p2, k3 : float
        Distortion coefficients in OpenCV's order (``calib.txt``'s order).
    """

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0

    def __post_init__(self) -> None:
        for name in ("fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "p1", "p2", "k3"):
            object.__setattr__(self, name, check_finite("CameraCalibration", name, getattr(self, name)))
        for name in ("fx_px", "fy_px"):
            check_positive("CameraCalibration", name, getattr(self, name))

    @property
    def camera_matrix(self) -> np.ndarray:
        """The 3x3 matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``."""
        return np.array([[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        """``(k1, k2, p1, p2, k3)``, OpenCV's order."""
        return np.array([self.k1, self.k2, self.p1, self.p2, self.k3])

    def as_list(self) -> list[float]:
        """The nine numbers in ``calib.txt`` order."""
        return [self.fx_px, self.fy_px, self.cx_px, self.cy_px, self.k1, self.k2, self.p1, self.p2, self.k3]

    @classmethod
    def from_text(cls, text: str, *, source: str = "calib.txt") -> "CameraCalibration":
        """Parse ``fx fy cx cy k1 k2 p1 p2 k3`` (4, 8 or 9 numbers; missing ones are 0).

        Raises
        ------
        ValueError
            Naming ``source`` and the offending token.
        """
        tokens = text.split()
        if len(tokens) not in (4, 5, 8, 9):
            raise ValueError(f"{source}: expected 'fx fy cx cy k1 k2 p1 p2 k3' (9 numbers), found {len(tokens)}")
        values = []
        for k, token in enumerate(tokens):
            try:
                values.append(float(token))
            except ValueError:
                raise ValueError(f"{source}: number {k + 1} ({token!r}) is not a number") from None
        try:
            return cls(*values)
        except (TypeError, ValueError) as err:
            raise ValueError(f"{source}: {err}") from None

    @classmethod
    def read(cls, path) -> "CameraCalibration":
        """Read a ``calib.txt`` file."""
        path = Path(path)
        return cls.from_text(path.read_text(encoding="utf-8", errors="replace"), source=str(path))


def distort_points(calib: CameraCalibration, u, v) -> tuple[np.ndarray, np.ndarray]:
    """The forward model: ideal pixel coordinates ``(u, v)`` to where the camera sees them.

    Closed form (module docstring); the reference for the tests of the
    OpenCV-based undistortion.
    """
    x = (np.asarray(u, dtype=np.float64) - calib.cx_px) / calib.fx_px
    y = (np.asarray(v, dtype=np.float64) - calib.cy_px) / calib.fy_px
    r2 = x * x + y * y
    radial = 1 + calib.k1 * r2 + calib.k2 * r2 * r2 + calib.k3 * r2 * r2 * r2
    xd = x * radial + 2 * calib.p1 * x * y + calib.p2 * (r2 + 2 * x * x)
    yd = y * radial + calib.p1 * (r2 + 2 * y * y) + 2 * calib.p2 * x * y
    return xd * calib.fx_px + calib.cx_px, yd * calib.fy_px + calib.cy_px


def _check(calib, sensor_size) -> None:
    if not isinstance(calib, CameraCalibration):
        raise TypeError(f"calib: expected a CameraCalibration, got {type(calib).__name__}")
    if not isinstance(sensor_size, SensorSize):
        raise TypeError(f"sensor_size: expected a SensorSize, got {type(sensor_size).__name__}")


def undistortion_map(calib: CameraCalibration, sensor_size: SensorSize) -> tuple[np.ndarray, np.ndarray]:
    """Undistorted float coordinates of every pixel, shape ``(height, width)`` each.

    ``cv2.undistortPoints`` with the same camera matrix as output, iterated
    to convergence (up to 100 iterations, 1e-12 normalised).
    """
    import cv2

    _check(calib, sensor_size)
    yy, xx = np.mgrid[0:sensor_size.height, 0:sensor_size.width]
    pts = np.stack([xx.ravel(), yy.ravel()], axis=1).astype(np.float64).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    out = cv2.undistortPoints(pts, calib.camera_matrix, calib.dist_coeffs, None, None, calib.camera_matrix, criteria)
    out = out.reshape(sensor_size.height, sensor_size.width, 2)
    return out[..., 0], out[..., 1]


def undistort_events(events, calib: CameraCalibration, sensor_size: SensorSize) -> tuple[np.ndarray, np.ndarray]:
    """Move each event to its undistorted pixel; drop those that land outside the sensor.

    Parameters
    ----------
    events : numpy.ndarray
        Events (any array :func:`evedge.events.as_events` accepts) inside ``sensor_size``.
    calib : CameraCalibration
    sensor_size : SensorSize

    Returns
    -------
    events : numpy.ndarray
        The kept events, in their order, with undistorted ``x``, ``y``.
    kept : numpy.ndarray
        bool, one per input event: False where the undistorted position is
        outside the sensor.

    Notes
    -----
    Policy: the undistorted coordinate is rounded to the nearest pixel
    (``numpy.rint``, halves to even), so events keep integer pixels and
    several distorted pixels may land on one undistorted pixel (and some
    undistorted pixels receive none: undistortion stretches the image
    towards its corners under barrel distortion). An event whose rounded
    position falls outside ``[0, width) x [0, height)`` is dropped and
    flagged in ``kept``. Times and polarities are unchanged.

    Examples
    --------
    >>> from evedge.events import make_events
    >>> ev = make_events([10, 0], [5, 0], [1, 2], [1, 0])
    >>> calib = CameraCalibration(40.0, 40.0, 20.0, 10.0, k1=-0.3)  # strong barrel distortion
    >>> out, kept = undistort_events(ev, calib, SensorSize(40, 20))
    >>> out["x"].tolist(), kept.tolist()
    ([10], [True, False])
    """
    _check(calib, sensor_size)
    events = validate_events(events, sensor_size, name="undistort_events: events")
    mx, my = undistortion_map(calib, sensor_size)
    ux = np.rint(mx).astype(np.int64)
    uy = np.rint(my).astype(np.int64)
    inside = (ux >= 0) & (ux < sensor_size.width) & (uy >= 0) & (uy < sensor_size.height)
    x = events["x"].astype(np.intp)
    y = events["y"].astype(np.intp)
    kept = inside[y, x]
    out = np.empty(int(kept.sum()), dtype=EVENT_DTYPE)
    out["x"] = ux[y[kept], x[kept]]
    out["y"] = uy[y[kept], x[kept]]
    out["t"] = events["t"][kept]
    out["p"] = events["p"][kept]
    return out, kept


def undistort_frames(frames: Frames, calib: CameraCalibration) -> Frames:
    """Undistort every image of ``frames`` (``cv2.undistort``: bilinear, black outside), same size.

    Parameters
    ----------
    frames : Frames
        uint8 or float images; boolean edge maps are refused (interpolating
        them is meaningless: undistort the events instead).
    calib : CameraCalibration

    Returns
    -------
    Frames
        Same times and dtype; pixel ``p`` of the result is the input sampled
        at ``distort_points(p)``.
    """
    import cv2

    if not isinstance(frames, Frames):
        raise TypeError(f"undistort_frames: expected Frames, got {type(frames).__name__}")
    if not isinstance(calib, CameraCalibration):
        raise TypeError(f"calib: expected a CameraCalibration, got {type(calib).__name__}")
    images = frames.images
    if images.dtype == bool:
        raise TypeError("undistort_frames: boolean edge maps cannot be interpolated; undistort the events instead")
    work = images if images.dtype in (np.uint8, np.float32, np.float64) else images.astype(np.float64)
    out = np.stack([cv2.undistort(img, calib.camera_matrix, calib.dist_coeffs) for img in work]) \
        if len(frames) else work.copy()
    return Frames(frames.t_us.copy(), out.astype(images.dtype, copy=False))
