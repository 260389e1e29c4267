"""Slow reference of the exact 3-D renderer's visibility: the implementation the numba kernel replaced.

Every projected box edge is sampled every 1/8 px; at each sample the faces 1e-8 px either side
are found by ray casting; runs of one (left, right) pair are pieces, their ends refined by 24
bisection passes; pieces on one image line are merged in Python (``_merge_collinear``).
Kept verbatim (but for names) as the reference of :mod:`evedge.sim._visibility`; the scanline
accumulation of the pieces' jumps (:func:`evedge.sim._scanline._piece_jumps`, not what this file
checks) is the production one; the prefix sums and the left border stay the old Python ones.
"""


import numpy as np

from evedge.sim._scanline import _piece_jumps
from evedge.sim.render3d import MeshRenderer, _cast_rays

_ZNEAR_M = 0.05


def _merge_collinear(p, q, left, right, tol_px=1e-6):
    """Merge pieces lying on one image line (each part of the line kept once).

    Box edges project onto one line when the camera lies in their common plane (a face seen
    edge-on, stacked boxes with aligned faces); the scanline accumulation must count each
    discontinuity once. Sides are re-expressed for the common orientation of the line.
    """
    d = q - p
    length = np.hypot(d[:, 0], d[:, 1])
    unit = d / length[:, None]
    flip = (unit[:, 0] < 0) | ((unit[:, 0] == 0) & (unit[:, 1] < 0))
    unit[flip] *= -1
    left, right = np.where(flip, right, left), np.where(flip, left, right)
    offset = unit[:, 0] * p[:, 1] - unit[:, 1] * p[:, 0]  # n . p with n = (-d_v, d_u)
    group = -np.ones(len(p), dtype=np.int64)
    n_groups = 0
    for k in range(len(p)):
        if group[k] < 0:
            same = ((group < 0) & (np.abs(unit - unit[k]).max(axis=1) < 1e-9)
                    & (np.abs(offset - offset[k]) < tol_px))
            group[same] = n_groups
            n_groups += 1
    out_p, out_q, out_l, out_r = [], [], [], []
    for g in range(n_groups):
        members = np.flatnonzero(group == g)
        k0 = members[0]
        # positions along the common line of every member's ends
        sp = p[members] @ unit[k0]
        sq = q[members] @ unit[k0]
        lo, hi = np.minimum(sp, sq), np.maximum(sp, sq)
        if members.size == 1:
            spans = [(lo[0], hi[0], k0)]
        else:
            ends = np.unique(np.concatenate([lo, hi]))
            spans = []
            for a, b in zip(ends[:-1], ends[1:]):
                cover = np.flatnonzero((lo <= 0.5 * (a + b)) & (hi >= 0.5 * (a + b)))
                if cover.size:
                    spans.append((a, b, members[cover[0]]))
        base = offset[k0] * np.array([-unit[k0, 1], unit[k0, 0]])  # foot of the line's normal
        for a, b, k in spans:
            out_p.append(base + a * unit[k0])
            out_q.append(base + b * unit[k0])
            out_l.append(left[k])
            out_r.append(right[k])
    if not out_p:
        return p[:0], q[:0], left[:0], right[:0]
    return np.array(out_p), np.array(out_q), np.array(out_l), np.array(out_r)


def _clip_segment(p0: np.ndarray, p1: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Liang-Barsky: parameters (a, b) of the part of ``p0 + s (p1 - p0)`` inside ``[lo, hi]``,
    or None."""
    a, b = 0.0, 1.0
    delta = p1 - p0
    for k in range(len(p0)):
        if abs(delta[k]) < 1e-15:
            if p0[k] < lo[k] or p0[k] > hi[k]:
                return None
            continue
        s_lo, s_hi = (lo[k] - p0[k]) / delta[k], (hi[k] - p0[k]) / delta[k]
        if s_lo > s_hi:
            s_lo, s_hi = s_hi, s_lo
        a, b = max(a, s_lo), min(b, s_hi)
        if a > b:
            return None
    return a, b


def _sampled_pieces(self, t_s: float, view_lo, view_hi):
    """Visible discontinuities at ``t_s`` as straight pieces, clipped to ``[view_lo, view_hi]``.

    Returns ``(start (K, 2), end (K, 2), left (K,), right (K,))``: image coordinates of the
    ends and the face identifiers on either side of each piece (left = side of the normal
    ``(-dv, du)``), constant along it. Every box edge is clipped to the near plane,
    projected, clipped to the view and sampled every 1/8 px; at each sample the faces seen
    1e-8 px to either side are found by exact ray casting; pieces are maximal runs of
    samples with one (left, right) pair that differ, their ends refined by bisection.
    """
    # bisection to 0.125 / 2**24 = 7e-9 px, matching the 1e-8 px side offset
    step_px, side_px, iterations = 0.125, 1e-8, 24
    rot = self.trajectory.rotation(t_s)
    centre = self.trajectory.position(t_s)
    focal, principal = np.array([self.fx, self.fy]), np.array([self.cx, self.cy])
    near_lo, near_hi = np.array([-np.inf, -np.inf, _ZNEAR_M]), np.full(3, np.inf)
    view_lo, view_hi = np.asarray(view_lo, float), np.asarray(view_hi, float)
    starts, ends = [], []
    for a_w, b_w in self._box_edges:
        a_c, b_c = (a_w - centre) @ rot, (b_w - centre) @ rot
        part = _clip_segment(a_c, b_c, near_lo, near_hi)
        if part is None:
            continue
        p, q = a_c + part[0] * (b_c - a_c), a_c + part[1] * (b_c - a_c)
        p, q = p[:2] / p[2] * focal + principal, q[:2] / q[2] * focal + principal
        part = _clip_segment(p, q, view_lo, view_hi)
        if part is None:
            continue
        p, q = p + part[0] * (q - p), p + part[1] * (q - p)
        if np.hypot(*(q - p)) > 1e-9:  # an edge seen end-on is a point of its neighbours
            starts.append(p)
            ends.append(q)
    none = (np.empty((0, 2)), np.empty((0, 2)), np.empty(0, np.int64), np.empty(0, np.int64))
    if not starts:
        return none
    starts, ends = np.array(starts), np.array(ends)
    delta = ends - starts
    length = np.hypot(delta[:, 0], delta[:, 1])
    normal = np.stack([-delta[:, 1], delta[:, 0]], axis=1) / length[:, None]
    values = self._lut

    def sides(seg, lam):
        """Key per sample: left * K + right when a discontinuity, else -1."""
        points = starts[seg] + lam[:, None] * delta[seg]
        both = np.concatenate([points + side_px * normal[seg], points - side_px * normal[seg]])
        rays = np.column_stack([(both - principal) / focal, np.ones(len(both))]) @ rot.T
        ids = _cast_rays(centre, rays, self._lo, self._hi)
        left, right = ids[: len(points)], ids[len(points):]
        return np.where(left != right, left * len(values) + right, -1)

    counts = np.maximum(np.ceil(length / step_px).astype(np.int64) + 1, 2)
    seg = np.repeat(np.arange(len(starts)), counts)
    offsets = np.cumsum(counts) - counts
    lam = (np.arange(seg.size) - offsets[seg]) / (counts[seg] - 1)
    key = sides(seg, lam)
    # changes of key between consecutive samples of one segment, refined by bisection
    same_seg = seg[:-1] == seg[1:]
    k = np.flatnonzero((key[:-1] != key[1:]) & same_seg)
    lo_lam, hi_lam, lo_key = lam[k].copy(), lam[k + 1].copy(), key[k]
    for _ in range(iterations):
        mid = 0.5 * (lo_lam + hi_lam)
        same = sides(seg[k], mid) == lo_key
        lo_lam, hi_lam = np.where(same, mid, lo_lam), np.where(same, hi_lam, mid)
    crossing = dict(zip(k.tolist(), (0.5 * (lo_lam + hi_lam)).tolist()))
    # pieces: maximal runs of one key >= 0 within a segment
    new_run = np.r_[True, (key[1:] != key[:-1]) | ~same_seg]
    end_run = np.r_[(key[1:] != key[:-1]) | ~same_seg, True]
    run_start = np.flatnonzero(new_run & (key >= 0))
    run_end = np.flatnonzero(end_run & (key >= 0))
    if run_start.size == 0:
        return none
    sid = seg[run_start]
    lam0 = np.array([crossing.get(f - 1, lam[f]) for f in run_start.tolist()])
    lam1 = np.array([crossing.get(e, lam[e]) for e in run_end.tolist()])
    p = starts[sid] + lam0[:, None] * delta[sid]
    q = starts[sid] + lam1[:, None] * delta[sid]
    return p, q, key[run_start] // len(values), key[run_start] % len(values)



class ReferenceRenderer(MeshRenderer):
    """A MeshRenderer whose exact intensity and edges use the sampled visibility, and the numpy
    prefix sums and left-border integral the numba kernels replaced."""

    def _visible_pieces(self, t_s):
        lo, hi = (-0.5, -0.5), (self.width - 0.5, self.height - 0.5)
        return _merge_collinear(*_sampled_pieces(self, t_s, lo, hi))

    def intensity(self, t_s, method="exact"):
        if method != "exact":
            return super().intensity(t_s, method)
        return np.clip(self._exact_intensity(t_s), 0.0, 1.0)

    def _exact_intensity(self, t_s: float) -> np.ndarray:
        """The left border's value plus the numpy prefix sum of each row's jumps (unclipped)."""
        p, q, left, right = self._pieces_at(t_s, True)
        acc = _piece_jumps(p, q, left, right, self._lut, self.width, self.height)
        return self._left_border(t_s, p, q)[:, None] + np.cumsum(acc, axis=1)[:, :self.width]

    def _left_border(self, t_s: float, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Mean intensity along the left image border ``u = -0.5`` over each row (H,)."""
        height = self.height
        ends = np.concatenate([p, q])
        cuts = ends[np.abs(ends[:, 0] + 0.5) < 1e-9, 1]
        breaks = np.unique(np.concatenate([np.arange(height + 1) - 0.5, np.clip(cuts, -0.5, height - 0.5)]))
        mids = 0.5 * (breaks[1:] + breaks[:-1])
        u = np.full(mids.size, -0.5 + 1e-7)
        rays = np.column_stack([(u - self.cx) / self.fx, (mids - self.cy) / self.fy, np.ones(mids.size)])
        ids = _cast_rays(self.trajectory.position(t_s), rays @ self.trajectory.rotation(t_s).T,
                         self._lo, self._hi)
        row = np.clip(np.floor(mids + 0.5).astype(np.int64), 0, height - 1)
        return np.bincount(row, weights=self._lut[ids] * np.diff(breaks), minlength=height)
