"""Rigid image-plane motion of a planar scene (camera moving parallel to a plane).

An object point ``q`` (pixels, its position at ``t = 0``) is seen at

    p(t) = c + R(theta(t)) (q - c) + s(t)

with rotation centre ``c``, translation ``s(t) = v0 t + a t^2 / 2 + A sin(phi(t))``
and angle ``theta(t) = theta0 + w0 t + alpha t^2 / 2 + Theta sin(phi(t))``. The
shared oscillation phase is a linear chirp ``phi(t) = 2 pi (f0 t + k t^2 / 2)``:
its frequency, hence the speed, grows with time (like the hand-held shapes
sequences of the Event Camera Dataset, slow at first and fast at the end).
The motion field is ``v(p) = theta'(t) J (p - c - s(t)) + s'(t)`` with
``J (x, y) = (-y, x)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def _check_vec(value, name: str) -> tuple[float, float]:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != (2,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"PlanarMotion.{name} must be two finite numbers, got {value!r}")
    return (float(arr[0]), float(arr[1]))


@dataclass(frozen=True)
class PlanarMotion:
    """Parameters of the rigid image-plane motion (see the module docstring)."""

    center_px: tuple[float, float] = (0.0, 0.0)
    velocity_px_s: tuple[float, float] = (0.0, 0.0)
    acceleration_px_s2: tuple[float, float] = (0.0, 0.0)
    amplitude_px: tuple[float, float] = (0.0, 0.0)
    angle_rad: float = 0.0
    angular_velocity_rad_s: float = 0.0
    angular_acceleration_rad_s2: float = 0.0
    angle_amplitude_rad: float = 0.0
    frequency_hz: float = 0.0
    chirp_hz_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("center_px", "velocity_px_s", "acceleration_px_s2", "amplitude_px"):
            object.__setattr__(self, name, _check_vec(getattr(self, name), name))
        for name in ("angle_rad", "angular_velocity_rad_s", "angular_acceleration_rad_s2",
                     "angle_amplitude_rad", "frequency_hz", "chirp_hz_s"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"PlanarMotion.{name} must be a finite number, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.frequency_hz < 0 or self.chirp_hz_s < 0:
            raise ValueError("PlanarMotion.frequency_hz and chirp_hz_s must be >= 0 (speed bound assumes it)")

    # --- state at time t (scalars or arrays of t) ---
    def _phase(self, t):
        return 2.0 * np.pi * (self.frequency_hz * t + 0.5 * self.chirp_hz_s * t * t)

    def _phase_rate(self, t):
        return 2.0 * np.pi * (self.frequency_hz + self.chirp_hz_s * t)

    def _state_scalar(self, t: float):
        # the same formulas in plain floats: the renderer calls this once per sample
        ph = 2.0 * math.pi * (self.frequency_hz * t + 0.5 * self.chirp_hz_s * t * t)
        sph = math.sin(ph)
        cph = math.cos(ph) * 2.0 * math.pi * (self.frequency_hz + self.chirp_hz_s * t)
        theta = (self.angle_rad + self.angular_velocity_rad_s * t
                 + 0.5 * self.angular_acceleration_rad_s2 * t * t + self.angle_amplitude_rad * sph)
        theta_dot = self.angular_velocity_rad_s + self.angular_acceleration_rad_s2 * t + self.angle_amplitude_rad * cph
        (v0x, v0y), (ax, ay), (amx, amy) = self.velocity_px_s, self.acceleration_px_s2, self.amplitude_px
        return (theta, theta_dot, v0x * t + 0.5 * ax * t * t + amx * sph, v0y * t + 0.5 * ay * t * t + amy * sph,
                v0x + ax * t + amx * cph, v0y + ay * t + amy * cph)

    def state(self, t_s):
        """Return ``theta, theta_dot, sx, sy, vx, vy`` at time(s) ``t_s``."""
        if isinstance(t_s, (float, int)):
            return self._state_scalar(float(t_s))
        t_s = np.asarray(t_s, dtype=np.float64)
        ph = self._phase(t_s)
        sph = np.sin(ph)
        cph = np.cos(ph) * self._phase_rate(t_s)
        theta = (self.angle_rad + self.angular_velocity_rad_s * t_s
                 + 0.5 * self.angular_acceleration_rad_s2 * t_s * t_s + self.angle_amplitude_rad * sph)
        theta_dot = self.angular_velocity_rad_s + self.angular_acceleration_rad_s2 * t_s + self.angle_amplitude_rad * cph
        (v0x, v0y), (ax, ay), (amx, amy) = self.velocity_px_s, self.acceleration_px_s2, self.amplitude_px
        sx = v0x * t_s + 0.5 * ax * t_s * t_s + amx * sph
        sy = v0y * t_s + 0.5 * ay * t_s * t_s + amy * sph
        vx = v0x + ax * t_s + amx * cph
        vy = v0y + ay * t_s + amy * cph
        return theta, theta_dot, sx, sy, vx, vy

    def to_image(self, qx, qy, t_s: float):
        """Image position at time ``t_s`` of object points ``(qx, qy)``."""
        theta, _, sx, sy, _, _ = self.state(t_s)
        c, s = math.cos(theta), math.sin(theta)
        cx, cy = self.center_px
        dx = np.asarray(qx) - cx
        dy = np.asarray(qy) - cy
        return cx + c * dx - s * dy + sx, cy + s * dx + c * dy + sy

    def flow_at(self, px, py, t_s):
        """Motion field (px/s) at image points ``(px, py)`` and time(s) ``t_s``."""
        _, w, sx, sy, vx, vy = self.state(t_s)
        cx, cy = self.center_px
        rx = np.asarray(px) - cx - sx
        ry = np.asarray(py) - cy - sy
        return vx - w * ry, vy + w * rx

    def max_speed_px_s(self, t0_s: float, t1_s: float, width: int, height: int) -> float:
        """Upper bound of the image speed over the sensor during ``[t0_s, t1_s]`` (``0 <= t0_s <= t1_s``)."""
        ends = (float(t0_s), float(t1_s))
        rate = 2.0 * math.pi * max(abs(self.frequency_hz + self.chirp_hz_s * t) for t in ends)
        lin = max(math.hypot(self.velocity_px_s[0] + self.acceleration_px_s2[0] * t,
                             self.velocity_px_s[1] + self.acceleration_px_s2[1] * t) for t in ends)
        trans = lin + math.hypot(*self.amplitude_px) * rate
        w = max(abs(self.angular_velocity_rad_s + self.angular_acceleration_rad_s2 * t) for t in ends)
        w += abs(self.angle_amplitude_rad) * rate
        if w == 0.0:
            return float(trans)
        tm = max(abs(t0_s), abs(t1_s))
        s_bound = (math.hypot(*self.velocity_px_s) * tm + 0.5 * math.hypot(*self.acceleration_px_s2) * tm * tm
                   + math.hypot(*self.amplitude_px))
        cx, cy = self.center_px
        r = max(math.hypot(x - cx, y - cy) for x in (-0.5, width - 0.5) for y in (-0.5, height - 0.5))
        return float(trans + w * (r + s_bound))
