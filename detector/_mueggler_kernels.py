"""numba kernel of the Mueggler et al. (ICRA 2015) lifetime estimator.

Private: called only by :mod:`evedge.detector.mueggler`, which validates every
input and owns the state arrays. All arrays are plain contiguous 1-D arrays.
The algorithm and its quirks are described in that module's docstring.
"""

import numpy as np
from numba import njit

from evedge._splitmix import GOLDEN as _GOLDEN
from evedge._splitmix import _splitmix64

#: SAE value of a pixel that never fired (no real relative time can reach it).
NEVER_FIRED = np.iinfo(np.int64).min


# Neighbour offsets for the flow direction rounded to 45 degrees, indexed by
# round(angle / 45) + 4 for angle in [-180, 180] (both ends give (-1, 0)).
_NEIGHBOUR_DX = np.array([-1, -1, 0, 1, 1, 1, 0, -1, -1], dtype=np.int64)
_NEIGHBOUR_DY = np.array([0, -1, -1, -1, 0, 1, 1, 1, 0], dtype=np.int64)


@njit(cache=True)
def _draw_index(seed, event_index, draw, n):
    """Uniform integer in ``[0, n)`` for one (seed, global event index, draw).

    Counter-based: the value depends only on its three keys, never on how
    the stream was cut into chunks.
    """
    key = _splitmix64(_splitmix64(np.uint64(seed)) ^ np.uint64(event_index))
    h = _splitmix64(key + np.uint64(draw) * _GOLDEN)
    # Top 53 bits times n, shifted back: exact in uint64 for n < 2**11.
    return np.int64(((h >> np.uint64(11)) * np.uint64(n)) >> np.uint64(53))


@njit(cache=True)
def _solve3(m, r):
    """Solve the 3x3 system ``m u = r`` (Gaussian elimination, partial pivoting).

    ``m`` (9 values, row-major) and ``r`` (3 values) are overwritten. Returns
    False when the system is singular.
    """
    for col in range(3):
        piv = col
        best = abs(m[3 * col + col])
        for row in range(col + 1, 3):
            v = abs(m[3 * row + col])
            if v > best:
                best = v
                piv = row
        if best == 0.0:
            return False
        if piv != col:
            for k in range(3):
                tmp = m[3 * col + k]
                m[3 * col + k] = m[3 * piv + k]
                m[3 * piv + k] = tmp
            tmp = r[col]
            r[col] = r[piv]
            r[piv] = tmp
        for row in range(col + 1, 3):
            f = m[3 * row + col] / m[3 * col + col]
            for k in range(col, 3):
                m[3 * row + k] -= f * m[3 * col + k]
            r[row] -= f * r[col]
    for col in range(2, -1, -1):
        acc = r[col]
        for k in range(col + 1, 3):
            acc -= m[3 * col + k] * r[k]
        r[col] = acc / m[3 * col + col]
    return True


@njit(cache=True)
def _mueggler_kernel(
    x,
    y,
    t_rel,
    pol,
    sae,
    prior_theta,
    prior_t,
    width,
    height,
    window,
    n_trials,
    inlier_threshold,
    mu,
    regularize,
    lambda_base,
    lambda_gain,
    lambda_decay_per_us,
    shift_prior_frame,
    seed,
    index0,
    out_lifetime_us,
    out_vx_px_s,
    out_vy_px_s,
    out_valid,
):
    """Run the estimator over events, updating the state arrays in place.

    Parameters
    ----------
    x, y, t_rel, pol : int64 arrays
        Event columns; ``t_rel`` in microseconds since the time origin,
        ``pol`` the SAE index (0 or 1).
    sae : int64 array (n_pol * height * width)
        Latest relative time per pixel, :data:`NEVER_FIRED` when none.
    prior_theta : float64 array (n_pol * height * width * 3)
        Plane predicted for each pixel by a neighbour (``(0, 0, 0)`` or
        ``(0, 0, 1)``: no prediction).
    prior_t : float64 array (n_pol * height * width)
        Predicted relative time of the next event at each pixel.
    inlier_threshold : float
        A candidate is acceptable with strictly more inliers than this.
    shift_prior_frame : bool
        Store the prediction in the target pixel's window coordinates
        (a correction; False reproduces the MATLAB code).
    index0 : int
        Global index of the first event (keys the random draws).
    out_* : arrays of len(x)
        Filled for every event (NaN / False when no estimate).
    """
    n_pts_max = window * window
    half = window // 2
    centre = float(half + 1)  # local coordinates are 1..N, as in the MATLAB code
    vals = np.empty(n_pts_max, dtype=np.int64)
    srt = np.empty(n_pts_max, dtype=np.int64)
    px = np.empty(n_pts_max, dtype=np.float64)
    py = np.empty(n_pts_max, dtype=np.float64)
    pt = np.empty(n_pts_max, dtype=np.float64)
    resid = np.empty(n_pts_max, dtype=np.float64)
    best_mask = np.zeros(n_pts_max, dtype=np.bool_)
    draws = np.empty(n_trials + 1, dtype=np.int64)
    m = np.empty(9, dtype=np.float64)
    r = np.empty(3, dtype=np.float64)
    plane = width * height

    for i in range(x.shape[0]):
        out_lifetime_us[i] = np.nan
        out_vx_px_s[i] = np.nan
        out_vy_px_s[i] = np.nan
        out_valid[i] = False
        xi = x[i]
        yi = y[i]
        ti = t_rel[i]
        base = pol[i] * plane
        own = base + yi * width + xi
        sae[own] = ti
        if xi < half or xi > width - 1 - half or yi < half or yi > height - 1 - half:
            continue

        # Window in MATLAB's column-major order (x outer, y inner).
        k = 0
        for lx in range(window):
            for ly in range(window):
                vals[k] = sae[base + (yi - half + ly) * width + (xi - half + lx)]
                k += 1
        # Median of all N^2 values, never-fired pixels counting as lowest
        # (the MATLAB code stores them as 0 and takes the median over all).
        for a in range(n_pts_max):
            v = vals[a]
            b = a - 1
            while b >= 0 and srt[b] > v:
                srt[b + 1] = srt[b]
                b -= 1
            srt[b + 1] = v
        med = srt[n_pts_max // 2]
        n_pts = 0
        k = 0
        for lx in range(window):
            for ly in range(window):
                v = vals[k]
                k += 1
                if v != NEVER_FIRED and v >= med:
                    px[n_pts] = float(lx + 1)
                    py[n_pts] = float(ly + 1)
                    pt[n_pts] = float(v)
                    n_pts += 1

        tc = float(ti)
        flag = False
        if n_pts >= 3:
            for d in range(n_trials + 1):
                draws[d] = _draw_index(seed, index0 + i, d, n_pts)
            best = 0
            for it in range(n_trials):
                j1 = draws[it]
                j2 = draws[it + 1]
                dx1 = px[j1] - centre
                dy1 = py[j1] - centre
                dt1 = pt[j1] - tc
                dx2 = px[j2] - centre
                dy2 = py[j2] - centre
                dt2 = pt[j2] - tc
                nz = dx1 * dy2 - dy1 * dx2
                if nz == 0.0:
                    # Collinear sample: the MATLAB code scores theta = (0, 0, 1)
                    # through the current event, i.e. the plane t = t_c.
                    nx = 0.0
                    ny = 0.0
                    nz = 1.0
                    d0 = 1.0
                else:
                    # Plane through the three points: normal n, n . p = d0;
                    # theta = n / d0 solves the sample system exactly.
                    nx = dy1 * dt2 - dt1 * dy2
                    ny = dt1 * dx2 - dx1 * dt2
                    d0 = nx * centre + ny * centre + nz * tc
                    if d0 == 0.0:
                        continue  # plane through the origin: a x + b y + c t = 1 cannot hold
                count = 0
                for j in range(n_pts):
                    q = (nx * (px[j] - centre) + ny * (py[j] - centre) + nz * (pt[j] - tc)) / d0
                    resid[j] = q * q
                    if resid[j] <= mu:
                        count += 1
                if count > inlier_threshold and count > best:
                    best = count
                    flag = True
                    for j in range(n_pts):
                        best_mask[j] = resid[j] <= mu

        valid = False
        a = 0.0
        b_ = 0.0
        c = 0.0
        vx = 0.0
        vy = 0.0
        sign = 1.0
        if flag:
            # Refinement: min sum (a x + b y + c t - 1)^2 + lam |theta - prior|^2,
            # a linear least-squares problem, solved in closed form with t
            # scaled by s (theta = D u, D = diag(1, 1, 1/s)) for conditioning.
            s = tc if tc > 0.0 else 1.0
            for q in range(9):
                m[q] = 0.0
            for q in range(3):
                r[q] = 0.0
            for j in range(n_pts):
                if best_mask[j]:
                    b0 = px[j]
                    b1 = py[j]
                    b2 = pt[j] / s
                    m[0] += b0 * b0
                    m[1] += b0 * b1
                    m[2] += b0 * b2
                    m[4] += b1 * b1
                    m[5] += b1 * b2
                    m[8] += b2 * b2
                    r[0] += b0
                    r[1] += b1
                    r[2] += b2
            m[3] = m[1]
            m[6] = m[2]
            m[7] = m[5]
            ta = prior_theta[3 * own]
            tb = prior_theta[3 * own + 1]
            tcp = prior_theta[3 * own + 2]
            prior_ok = not (tcp == 0.0 or (ta == 0.0 and tb == 0.0 and tcp == 1.0))
            if regularize and prior_ok:
                lam = lambda_base + lambda_gain * np.exp(-lambda_decay_per_us * abs(tc - prior_t[own]))
                m[0] += lam
                m[4] += lam
                m[8] += lam / (s * s)
                r[0] += lam * ta
                r[1] += lam * tb
                r[2] += lam * tcp / s
            if _solve3(m, r):
                a = r[0]
                b_ = r[1]
                c = r[2] / s
                sign = 1.0
                if c < 0.0:
                    sign = -1.0
                    a = -a
                    b_ = -b_
                    c = -c
                g2 = a * a + b_ * b_
                if c > 0.0 and g2 > 0.0:
                    life = np.sqrt(g2) / c
                    if np.isfinite(life):
                        valid = True
                        vx = -c * a / g2  # px/us
                        vy = -c * b_ / g2
                        out_lifetime_us[i] = life
                        out_vx_px_s[i] = vx * 1e6
                        out_vy_px_s[i] = vy * 1e6
                        out_valid[i] = True

        if valid:
            # Predict the plane and time at the neighbour in the flow direction.
            q = np.arctan2(vy, vx) * (180.0 / np.pi) / 45.0
            kk = np.int64(np.floor(abs(q) + 0.5))  # MATLAB round: half away from zero
            if q < 0.0:
                kk = -kk
            ndx = _NEIGHBOUR_DX[kk + 4]
            ndy = _NEIGHBOUR_DY[kk + 4]
            dist = np.sqrt(float(ndx * ndx + ndy * ndy))
            vn = (vx * ndx + vy * ndy) / dist
            target = base + (yi + ndy) * width + (xi + ndx)
            if shift_prior_frame:
                # The same plane in the neighbour's window coordinates
                # (x_l -> x_l + dx): theta / (1 - a dx - b dy), unflipped.
                scale = sign * (1.0 - sign * (a * ndx + b_ * ndy))
                if scale == 0.0:
                    prior_theta[3 * target] = 0.0
                    prior_theta[3 * target + 1] = 0.0
                    prior_theta[3 * target + 2] = 1.0
                else:
                    prior_theta[3 * target] = a / scale
                    prior_theta[3 * target + 1] = b_ / scale
                    prior_theta[3 * target + 2] = c / scale
            else:
                # As the MATLAB code: the sign-flipped plane in this event's own
                # window coordinates, which are shifted by (dx, dy) for the target.
                prior_theta[3 * target] = a
                prior_theta[3 * target + 1] = b_
                prior_theta[3 * target + 2] = c
            prior_t[target] = dist / vn + tc
        else:
            # No estimate: the MATLAB code stores "no prediction" at the pixel itself.
            prior_theta[3 * own] = 0.0
            prior_theta[3 * own + 1] = 0.0
            prior_theta[3 * own + 2] = 1.0
            prior_t[own] = 0.0
