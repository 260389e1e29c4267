"""Camera trajectories and IMU truth against closed forms (constant screw motion, circular motion)."""

import math

import numpy as np
import pytest

from evedge.sim.trajectory import (
    IMU_DTYPE,
    CameraTrajectory,
    KeyframeTrajectory,
    imu,
    imu_table,
    rotation_from_rpy,
)


def _keyframes_of(tr, times):
    return KeyframeTrajectory(times, [tr.position(t) for t in times], [tr.rotation(t) for t in times])


def test_keyframes_of_constant_velocity_reproduce_it():
    ct = CameraTrajectory((0.1, -0.2, 0.3), (0.5, 0.1, -0.2), (0.1, 0.2, -0.3), (0.3, -0.6, 0.4))
    kt = _keyframes_of(ct, np.linspace(0.0, 1.0, 11))
    for t in np.linspace(0.0, 1.0, 37):
        np.testing.assert_allclose(kt.rotation(t), ct.rotation(t), atol=1e-9)
        np.testing.assert_allclose(kt.position(t), ct.position(t), atol=1e-9)
        np.testing.assert_allclose(kt.angular_velocity(t), ct.angular_velocity(t), atol=1e-9)
        np.testing.assert_allclose(kt.linear_velocity(t), ct.linear_velocity(t), atol=1e-9)
        np.testing.assert_allclose(kt.linear_acceleration(t), 0.0, atol=1e-9)
    # two keyframes: a straight line at constant speed
    two = KeyframeTrajectory([0.0, 2.0], [[0, 0, 0], [1.0, 2.0, 0]], [np.eye(3), np.eye(3)])
    np.testing.assert_allclose(two.position(0.5), [0.25, 0.5, 0.0], atol=1e-15)
    np.testing.assert_allclose(two.linear_velocity(1.3), [0.5, 1.0, 0.0], atol=1e-15)


def test_vectorised_kinematics_match_pointwise():
    ct = CameraTrajectory((0.1, -0.2, 0.3), (0.5, 0.1, -0.2), (0.1, 0.2, -0.3), (0.3, -0.6, 0.4))
    kt = _keyframes_of(ct, np.linspace(0.0, 1.0, 5))
    t = np.array([0.0, 0.21, 0.5, 0.93, 1.0])
    for tr in (ct, kt):
        rot, centre, vel, w = tr.kinematics(t)
        for k, tk in enumerate(t):
            np.testing.assert_allclose(rot[k], tr.rotation(tk), atol=1e-14)
            np.testing.assert_allclose(centre[k], tr.position(tk), atol=1e-14)
            np.testing.assert_allclose(vel[k], tr.linear_velocity(tk), atol=1e-14)
            np.testing.assert_allclose(w[k], tr.angular_velocity(tk), atol=1e-14)


def test_imu_at_rest_reads_gravity_up_and_constant_rotation_rate():
    tr = CameraTrajectory((0, 0, 0), (0, 0, 0), (0, 0, 0), (0.2, -0.4, 0.1))
    gyro, acc = imu(tr, [0.0, 0.7, 2.0])
    np.testing.assert_allclose(gyro, [[0.2, -0.4, 0.1]] * 3, atol=1e-15)
    # specific force R^T (0 - g): magnitude g, pointing up (world -y) in the rotating camera frame
    for k, t in enumerate((0.0, 0.7, 2.0)):
        np.testing.assert_allclose(tr.rotation(t) @ acc[k], [0.0, -9.80665, 0.0], atol=1e-12)
    # constant velocity: no acceleration, so only gravity
    moving = CameraTrajectory((0, 0, 0), (3.0, 1.0, 0), (0, 0, 0), (0, 0, 0))
    np.testing.assert_allclose(imu(moving, [0.5])[1], [[0.0, -9.80665, 0.0]], atol=1e-12)


def test_circular_motion_imu_matches_closed_form():
    # camera on a circle of radius r about the world origin in the x-z plane, always facing the
    # centre: gyro (0, -omega, 0), accelerometer (gravity off) omega^2 r forward (centripetal)
    r, om = 2.0, 1.5
    ts = np.linspace(0, 2 * math.pi / om, 41)
    kt = KeyframeTrajectory(ts, [(r * math.sin(om * t), 0, -r * math.cos(om * t)) for t in ts],
                            [rotation_from_rpy(0, 0, -om * t) for t in ts])
    t = np.linspace(0.5, 3.5, 13)
    gyro, acc = imu(kt, t, gravity_m_s2=(0.0, 0.0, 0.0))
    np.testing.assert_allclose(gyro, np.tile([0.0, -om, 0.0], (t.size, 1)), atol=1e-9)
    np.testing.assert_allclose(acc[:, 2], om * om * r, rtol=3e-3)  # cubic spline: O(h^2) in acceleration
    np.testing.assert_allclose(acc[:, :2], 0.0, atol=2e-3)
    np.testing.assert_allclose(np.linalg.norm([kt.linear_velocity(x) for x in t], axis=1), om * r, rtol=1e-4)
    # the bounds cover the true rates
    assert om * r <= kt.speed_bound_m_s(0.5, 1.5) <= 1.2 * om * r
    assert np.all(kt.angular_rate_bound_rad_s(0.5, 1.5) >= [0.0, om, 0.0])


def test_imu_table_rows():
    tr = CameraTrajectory((0, 0, 0), (0, 0, 0), (0, 0, 0), (0, 0.5, 0))
    rows = imu_table(tr, 200.0, 0.1)
    assert rows.dtype == IMU_DTYPE and rows.shape == (21,)
    assert rows["t_us"][-1] == 100000 and np.all(np.diff(rows["t_us"]) == 5000)
    np.testing.assert_allclose(rows["wy_rad_s"], 0.5)
    with pytest.raises(ValueError, match="rate_hz"):
        imu_table(tr, 0.0, 1.0)


@pytest.mark.parametrize("kwargs, message", [
    (dict(times_s=[0.0]), "at least 2"),
    (dict(times_s=[0.0, 0.0]), "strictly increasing"),
    (dict(positions_m=[[0, 0, 0]] * 3), "positions_m"),
    (dict(rotations=[np.eye(3), 2 * np.eye(3)]), "proper rotation"),
    (dict(rotations=[np.eye(3), -np.eye(3)]), "proper rotation"),
])
def test_keyframes_reject_bad_input(kwargs, message):
    args = dict(times_s=[0.0, 1.0], positions_m=[[0, 0, 0], [1, 0, 0]], rotations=[np.eye(3), np.eye(3)])
    args.update(kwargs)
    if len(args["times_s"]) == 1:
        args["positions_m"], args["rotations"] = args["positions_m"][:1], args["rotations"][:1]
    with pytest.raises(ValueError, match=message):
        KeyframeTrajectory(**args)


def test_keyframe_time_range_is_checked():
    kt = KeyframeTrajectory([0.0, 1.0], [[0, 0, 0], [1, 0, 0]], [np.eye(3), np.eye(3)])
    with pytest.raises(ValueError, match="outside the keyframes"):
        kt.position(1.5)
    with pytest.raises(ValueError, match="outside the keyframes"):
        kt.kinematics(np.array([0.5, -0.1]))


def test_imu_table_never_reads_past_the_keyframes():
    # keyframes end at 10000.6 us; the second IMU time 10000.55 us rounds up to 10001 us, past the end:
    # it is read at the end instead of raising
    kt = KeyframeTrajectory([0.0, 0.0100006], [[0, 0, 0], [0.01, 0, 0]], [np.eye(3), np.eye(3)])
    rows = imu_table(kt, 1.0 / 0.01000055, 0.0100006)
    assert rows["t_us"].tolist() == [0, 10001] and np.isfinite(rows["ax_m_s2"]).all()
    with pytest.raises(ValueError, match="outside the keyframes"):
        imu(kt, [0.010001])
