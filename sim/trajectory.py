"""Camera trajectories of the 3-D scenes: constant velocity and keyframed splines, with IMU truth.

Frames follow OpenCV: x right, y down, z forward (the camera looks along +z of its own
frame). A trajectory gives the camera-to-world pose ``[[R(t), c(t)], [0, 1]]`` at any time,
its derivatives (world linear velocity and acceleration, body angular velocity) and bounds of
them over an interval (used to bound the image speed, hence the sampling step).

- :class:`CameraTrajectory`: constant linear and angular velocity (a screw motion);
- :class:`KeyframeTrajectory`: keyframed positions and orientations, positions by a cubic
  spline (twice continuously differentiable), orientations by scipy's
  :class:`~scipy.spatial.transform.RotationSpline` (continuous angular rate and acceleration);
  keyframes of a constant-velocity motion reproduce it (tested to 1e-9).

IMU truth (:func:`imu`): the gyroscope reads the body angular velocity; the accelerometer the
specific force ``R(t)^T (a(t) - g)`` in the camera frame, ``g`` the gravity vector in the world
frame, by default ``(0, 9.80665, 0)`` m/s^2 (world +y is down), so a camera at rest with
``R = I`` reads ``(0, -9.80665, 0)``: up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["CameraTrajectory", "KeyframeTrajectory", "GRAVITY_M_S2", "IMU_DTYPE", "imu", "imu_table",
           "rotation_from_rpy"]

#: Default gravity in the world frame (OpenCV axes, y down), m/s^2 (standard gravity).
GRAVITY_M_S2 = (0.0, 9.80665, 0.0)

#: IMU truth rows of a recording: time, gyroscope (body rad/s), accelerometer (specific force, camera frame).
IMU_DTYPE = np.dtype([("t_us", np.int64), ("wx_rad_s", np.float64), ("wy_rad_s", np.float64),
                      ("wz_rad_s", np.float64), ("ax_m_s2", np.float64), ("ay_m_s2", np.float64),
                      ("az_m_s2", np.float64)])


def _vector(value, name: str, length: int = 3) -> tuple[float, ...]:
    """Return ``value`` as a tuple of ``length`` finite floats or raise naming ``name``."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be a sequence of {length} numbers, got {value!r}") from exc
    if arr.shape != (length,):
        raise ValueError(f"{name} must have {length} elements, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return tuple(float(x) for x in arr)


def _finite(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    return value


def _skew(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _so3_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrix ``exp([w]x)`` (Rodrigues' formula)."""
    theta = float(np.linalg.norm(w))
    k = _skew(w)
    if theta < 1e-12:
        return np.eye(3) + k
    return np.eye(3) + (math.sin(theta) / theta) * k + ((1.0 - math.cos(theta)) / theta**2) * (k @ k)


def rotation_from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Camera-to-world rotation of roll/pitch/yaw angles in OpenCV axes.

    ``R = Ry(yaw) @ Rx(pitch) @ Rz(roll)``: yaw about the (down) y axis, then pitch about the
    (right) x axis, then roll about the (forward, optical) z axis; the aerospace z-y-x sequence
    mapped onto OpenCV axes (forward z, right x, down y). Positive yaw turns the view towards +x.

    Examples
    --------
    >>> import numpy as np
    >>> np.round(rotation_from_rpy(0.0, 0.0, np.pi / 2) @ [0, 0, 1], 12) + 0.0
    array([1., 0., 0.])
    """
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rz = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    return ry @ rx @ rz


class _Trajectory:
    """Shared methods: the pose from ``rotation`` and ``position``; the base of the trajectory types."""

    def pose(self, t_s: float) -> np.ndarray:
        """Camera-to-world 4x4 matrix at time ``t_s`` (OpenCV camera axes)."""
        pose = np.eye(4)
        pose[:3, :3] = self.rotation(t_s)
        pose[:3, 3] = self.position(t_s)
        return pose


@dataclass(frozen=True)
class CameraTrajectory(_Trajectory):
    """Constant-velocity 6-DOF camera motion.

    Parameters
    ----------
    position_m : tuple of 3 float
        Camera centre at t = 0, world frame, metres.
    velocity_m_s : tuple of 3 float
        Constant linear velocity of the camera centre, world frame, m/s.
    rotation_rpy_rad : tuple of 3 float
        Orientation at t = 0 as (roll, pitch, yaw), see :func:`rotation_from_rpy`
        (roll about the optical axis z, pitch about x, yaw about y).
    angular_velocity_rad_s : tuple of 3 float
        Constant angular velocity ``(wx, wy, wz)`` in the camera's own frame (OpenCV axes), rad/s:
        ``wy`` is the yaw rate, ``wx`` the pitch rate, ``wz`` the roll rate.

    Notes
    -----
    ``R(t) = R0 @ expm([w]x t)`` and ``c(t) = c0 + v t``; the camera-to-world pose is
    ``[[R(t), c(t)], [0, 1]]``. A body-frame angular velocity keeps the motion a true
    constant-velocity screw motion (roll/pitch/yaw rates would not be constant in general).

    Examples
    --------
    >>> tr = CameraTrajectory((0, 0, 0), (1.0, 0, 0), (0, 0, 0), (0, 0, 0))
    >>> tr.position(0.5)
    array([0.5, 0. , 0. ])
    """

    position_m: tuple[float, float, float]
    velocity_m_s: tuple[float, float, float]
    rotation_rpy_rad: tuple[float, float, float]
    angular_velocity_rad_s: tuple[float, float, float]

    def __post_init__(self):
        for name in ("position_m", "velocity_m_s", "rotation_rpy_rad", "angular_velocity_rad_s"):
            object.__setattr__(self, name, _vector(getattr(self, name), f"CameraTrajectory.{name}"))

    def rotation(self, t_s: float) -> np.ndarray:
        """Camera-to-world rotation (3, 3) at time ``t_s``."""
        t_s = _finite(t_s, "t_s")
        r0 = rotation_from_rpy(*self.rotation_rpy_rad)
        return r0 @ _so3_exp(np.asarray(self.angular_velocity_rad_s) * t_s)

    def position(self, t_s: float) -> np.ndarray:
        """Camera centre (3,) in the world frame at time ``t_s``, metres."""
        t_s = _finite(t_s, "t_s")
        return np.asarray(self.position_m) + np.asarray(self.velocity_m_s) * t_s

    def linear_velocity(self, t_s: float) -> np.ndarray:
        """World-frame velocity (3,) of the camera centre at ``t_s``, m/s."""
        _finite(t_s, "t_s")
        return np.asarray(self.velocity_m_s, dtype=np.float64)

    def linear_acceleration(self, t_s: float) -> np.ndarray:
        """World-frame acceleration (3,) of the camera centre at ``t_s``, m/s^2 (zero)."""
        _finite(t_s, "t_s")
        return np.zeros(3)

    def angular_velocity(self, t_s: float) -> np.ndarray:
        """Body-frame angular velocity (3,) at ``t_s``, rad/s (``R^T dR/dt = [w]x``)."""
        _finite(t_s, "t_s")
        return np.asarray(self.angular_velocity_rad_s, dtype=np.float64)

    def kinematics(self, t_s: np.ndarray):
        """Vectorised state at times ``t_s`` (N,): rotations (N, 3, 3), centres, world velocities, body rates (N, 3)."""
        t = np.asarray(t_s, dtype=np.float64).reshape(-1)
        w = np.asarray(self.angular_velocity_rad_s)
        k = _skew(w)
        theta = float(np.linalg.norm(w))
        if theta < 1e-300:
            expo = np.broadcast_to(np.eye(3), (t.size, 3, 3))
        else:
            a = np.where(np.abs(theta * t) < 1e-12, t, np.sin(theta * t) / theta)
            b = np.where(np.abs(theta * t) < 1e-12, 0.0, (1.0 - np.cos(theta * t)) / theta**2)
            expo = np.eye(3) + a[:, None, None] * k + b[:, None, None] * (k @ k)
        rot = rotation_from_rpy(*self.rotation_rpy_rad) @ expo
        centre = np.asarray(self.position_m) + np.asarray(self.velocity_m_s) * t[:, None]
        vel = np.broadcast_to(np.asarray(self.velocity_m_s), (t.size, 3))
        return rot, centre, vel, np.broadcast_to(w, (t.size, 3))

    def speed_bound_m_s(self, t0_s: float, t1_s: float) -> float:
        """Upper bound of ``|dc/dt|`` over ``[t0_s, t1_s]`` (exact: the speed is constant)."""
        return float(np.linalg.norm(self.velocity_m_s))

    def angular_rate_bound_rad_s(self, t0_s: float, t1_s: float) -> np.ndarray:
        """Upper bounds (3,) of ``|wx|, |wy|, |wz|`` over ``[t0_s, t1_s]`` (exact)."""
        return np.abs(np.asarray(self.angular_velocity_rad_s, dtype=np.float64))


class KeyframeTrajectory(_Trajectory):
    """Camera poses at keyframes, interpolated smoothly.

    Parameters
    ----------
    times_s : sequence of float
        Keyframe times, strictly increasing, at least 2 (seconds). The trajectory is defined
        on ``[times_s[0], times_s[-1]]``; other times raise ``ValueError``.
    positions_m : (K, 3) array_like
        Camera centres at the keyframes, world frame, metres.
    rotations : (K, 3, 3) array_like
        Camera-to-world rotation matrices at the keyframes (see :func:`rotation_from_rpy`);
        consecutive keyframes are joined by the shorter rotation.

    Notes
    -----
    Positions: :class:`scipy.interpolate.CubicSpline` with ``bc_type="not-a-knot"`` (2
    keyframes: the straight line at constant speed; 3 or more: C2, and positions on a line at
    uniform speed stay so). Orientations: :class:`scipy.spatial.transform.RotationSpline`,
    whose first derivative is the body-frame angular velocity ``w`` with ``R^T dR/dt = [w]x``.
    The speed bound is rigorous (the acceleration of a cubic spline is piecewise linear);
    the angular-rate bound is the largest rate on a grid of 1/32 of the interval plus the
    largest angular acceleration there times the grid step, doubled: a bound for the smooth
    splines of camera paths, not a proof (it only sets the largest sampling step).

    Examples
    --------
    >>> import numpy as np
    >>> tr = KeyframeTrajectory([0.0, 1.0], [[0, 0, 0], [1.0, 0, 0]], [np.eye(3), np.eye(3)])
    >>> tr.position(0.25)
    array([0.25, 0.  , 0.  ])
    """

    def __init__(self, times_s, positions_m, rotations):
        from scipy.interpolate import CubicSpline
        from scipy.spatial.transform import Rotation, RotationSpline

        times = np.asarray(times_s, dtype=np.float64)
        if times.ndim != 1 or times.size < 2:
            raise ValueError(f"KeyframeTrajectory: times_s needs at least 2 keyframe times, got shape {times.shape}")
        if not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
            raise ValueError(f"KeyframeTrajectory: times_s must be finite and strictly increasing, got {times.tolist()}")
        pos = np.asarray(positions_m, dtype=np.float64)
        if pos.shape != (times.size, 3) or not np.all(np.isfinite(pos)):
            raise ValueError(f"KeyframeTrajectory: positions_m must be {times.size} finite [x, y, z] rows, "
                             f"got shape {pos.shape}")
        rot = np.asarray(rotations, dtype=np.float64)
        if rot.shape != (times.size, 3, 3) or not np.all(np.isfinite(rot)):
            raise ValueError(f"KeyframeTrajectory: rotations must be {times.size} 3x3 matrices, got shape {rot.shape}")
        err = np.abs(np.einsum("kji,kjl->kil", rot, rot) - np.eye(3)).max()
        if err > 1e-6 or np.any(np.linalg.det(rot) < 0):
            raise ValueError(f"KeyframeTrajectory: rotations must be proper rotation matrices (R^T R = I to 1e-6, "
                             f"det +1), got an error of {err:.2g}")
        self.times_s = times
        self.positions_m = pos
        self.rotations = rot
        self._pos = CubicSpline(times, pos, axis=0, bc_type="not-a-knot")
        self._vel = self._pos.derivative(1)
        self._acc = self._pos.derivative(2)
        self._rot = RotationSpline(times, Rotation.from_matrix(rot))

    def _time(self, t_s) -> float:
        t_s = _finite(t_s, "t_s")
        lo, hi = self.times_s[0], self.times_s[-1]
        if not lo - 1e-12 <= t_s <= hi + 1e-12:
            raise ValueError(f"t_s = {t_s} is outside the keyframes' time range [{lo}, {hi}]")
        return min(max(t_s, lo), hi)

    def rotation(self, t_s: float) -> np.ndarray:
        """Camera-to-world rotation (3, 3) at time ``t_s``."""
        return self._rot(self._time(t_s)).as_matrix()

    def position(self, t_s: float) -> np.ndarray:
        """Camera centre (3,) in the world frame at time ``t_s``, metres."""
        return np.asarray(self._pos(self._time(t_s)), dtype=np.float64)

    def linear_velocity(self, t_s: float) -> np.ndarray:
        """World-frame velocity (3,) of the camera centre at ``t_s``, m/s."""
        return np.asarray(self._vel(self._time(t_s)), dtype=np.float64)

    def linear_acceleration(self, t_s: float) -> np.ndarray:
        """World-frame acceleration (3,) of the camera centre at ``t_s``, m/s^2."""
        return np.asarray(self._acc(self._time(t_s)), dtype=np.float64)

    def angular_velocity(self, t_s: float) -> np.ndarray:
        """Body-frame angular velocity (3,) at ``t_s``, rad/s (``R^T dR/dt = [w]x``)."""
        return np.asarray(self._rot(self._time(t_s), 1), dtype=np.float64)

    def kinematics(self, t_s: np.ndarray):
        """Vectorised state at times ``t_s`` (N,): rotations (N, 3, 3), centres, world velocities, body rates (N, 3)."""
        t = np.asarray(t_s, dtype=np.float64).reshape(-1)
        lo, hi = self.times_s[0], self.times_s[-1]
        if t.size and not (np.all(np.isfinite(t)) and t.min() >= lo - 1e-12 and t.max() <= hi + 1e-12):
            raise ValueError(f"t_s outside the keyframes' time range [{lo}, {hi}]")
        t = np.clip(t, lo, hi)
        return (self._rot(t).as_matrix().reshape(-1, 3, 3), self._pos(t).reshape(-1, 3),
                self._vel(t).reshape(-1, 3), np.asarray(self._rot(t, 1)).reshape(-1, 3))

    def _grid(self, t0_s, t1_s):
        t0, t1 = self._time(t0_s), self._time(t1_s)
        if t1 < t0:
            raise ValueError(f"t1_s must be >= t0_s, got t0_s={t0_s}, t1_s={t1_s}")
        knots = self.times_s[(self.times_s > t0) & (self.times_s < t1)]
        return np.unique(np.concatenate([np.linspace(t0, t1, 33), knots])), (t1 - t0) / 32

    def speed_bound_m_s(self, t0_s: float, t1_s: float) -> float:
        """Upper bound of ``|dc/dt|`` over ``[t0_s, t1_s]`` (rigorous, see Notes)."""
        grid, step = self._grid(t0_s, t1_s)
        speed = np.linalg.norm(self._vel(grid), axis=1).max()
        # the acceleration is linear between knots: its largest norm is on the grid (knots included)
        acc = np.linalg.norm(self._acc(grid), axis=1).max()
        return float(speed + acc * step / 2)

    def angular_rate_bound_rad_s(self, t0_s: float, t1_s: float) -> np.ndarray:
        """Bounds (3,) of ``|wx|, |wy|, |wz|`` over ``[t0_s, t1_s]`` (sampled with a margin, see Notes)."""
        grid, step = self._grid(t0_s, t1_s)
        rate = np.abs(self._rot(grid, 1)).max(axis=0)
        acc = np.abs(self._rot(grid, 2)).max(axis=0)
        return 2.0 * (rate + acc * step)


def imu(trajectory, t_s, gravity_m_s2=GRAVITY_M_S2) -> tuple[np.ndarray, np.ndarray]:
    """IMU truth sampled from a trajectory: gyroscope and accelerometer readings in the camera frame.

    Parameters
    ----------
    trajectory : CameraTrajectory or KeyframeTrajectory
    t_s : array_like of float
        Sample times (seconds).
    gravity_m_s2 : tuple of 3 float
        Gravity in the world frame (default :data:`GRAVITY_M_S2`, world +y down).

    Returns
    -------
    angular_velocity_rad_s : (N, 3) float64
        Body-frame angular velocity (the gyroscope, noise-free).
    linear_acceleration_m_s2 : (N, 3) float64
        Specific force ``R^T (a - g)`` in the camera frame (the accelerometer, noise-free).

    Examples
    --------
    >>> tr = CameraTrajectory((0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0, 0))
    >>> gyro, acc = imu(tr, [0.0])
    >>> acc[0] + 0.0
    array([ 0.     , -9.80665,  0.     ])
    """
    times = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
    if times.ndim != 1 or not np.all(np.isfinite(times)):
        raise ValueError("imu: t_s must be a 1-D array of finite times")
    g = np.asarray(_vector(gravity_m_s2, "gravity_m_s2"))
    gyro = np.empty((times.size, 3))
    acc = np.empty((times.size, 3))
    for k, t in enumerate(times.tolist()):
        gyro[k] = trajectory.angular_velocity(t)
        acc[k] = trajectory.rotation(t).T @ (trajectory.linear_acceleration(t) - g)
    return gyro, acc


def imu_table(trajectory, rate_hz: float, duration_s: float, gravity_m_s2=GRAVITY_M_S2) -> np.ndarray:
    """IMU truth at ``k / rate_hz`` for ``k = 0, 1, ...`` up to ``duration_s``, as :data:`IMU_DTYPE` rows.

    Times are rounded to whole microseconds first and the readings taken at those times (at
    ``duration_s`` for a last time rounded past it).

    Examples
    --------
    >>> tr = CameraTrajectory((0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0.5, 0))
    >>> rows = imu_table(tr, 100.0, 0.05)
    >>> rows["t_us"].tolist(), float(rows["wy_rad_s"][3])
    ([0, 10000, 20000, 30000, 40000, 50000], 0.5)
    """
    rate_hz, duration_s = _finite(rate_hz, "rate_hz"), _finite(duration_s, "duration_s")
    if rate_hz <= 0 or duration_s < 0:
        raise ValueError(f"imu_table: rate_hz must be > 0 and duration_s >= 0, got {rate_hz}, {duration_s}")
    n = int(math.floor(duration_s * rate_hz + 1e-9)) + 1
    t_us = np.rint(np.arange(n) / rate_hz * 1e6).astype(np.int64)
    # a time rounded up past the end (duration_s not whole microseconds) is read at the end
    gyro, acc = imu(trajectory, np.minimum(t_us * 1e-6, duration_s), gravity_m_s2)
    out = np.empty(n, dtype=IMU_DTYPE)
    out["t_us"] = t_us
    for k, axis in enumerate("xyz"):
        out[f"w{axis}_rad_s"] = gyro[:, k]
        out[f"a{axis}_m_s2"] = acc[:, k]
    return out
