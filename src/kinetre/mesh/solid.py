"""Points against a triangle surface: whether they lie inside it (the generalized winding number) and how far
they are from it. Exact at the triangles' own resolution, so a small part (a bolt, a thumb) gets as sure an
answer as a big one.
"""
from __future__ import annotations

import numpy as np

from ..jit import njit


@njit(cache=True)
def _winding(points, vertices, faces, out):
    for i in range(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        total = 0.0
        for f in range(faces.shape[0]):
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            ax, ay, az = vertices[a, 0] - px, vertices[a, 1] - py, vertices[a, 2] - pz
            bx, by, bz = vertices[b, 0] - px, vertices[b, 1] - py, vertices[b, 2] - pz
            cx, cy, cz = vertices[c, 0] - px, vertices[c, 1] - py, vertices[c, 2] - pz
            la = np.sqrt(ax * ax + ay * ay + az * az)
            lb = np.sqrt(bx * bx + by * by + bz * bz)
            lc = np.sqrt(cx * cx + cy * cy + cz * cz)
            num = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
            den = (la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (ax * cx + ay * cy + az * cz) * lb
                   + (bx * cx + by * cy + bz * cz) * la)
            total += np.arctan2(num, den)
        out[i] = total / (2.0 * np.pi)


def winding_numbers(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(P,) the generalized winding number of every point with respect to the triangles `faces` of
    `vertices`: the solid angle they subtend over 4π (Van Oosterom and Strackee's formula per triangle).
    About 1 inside a closed outward-wound surface and 0 outside; an open surface (a plate, a shell with a hole)
    gives the fraction it wraps round the point, so a threshold of 1/2 still tells inside from outside."""
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.zeros(len(points))
    _winding(points, np.ascontiguousarray(vertices, dtype=np.float64),
             np.ascontiguousarray(np.asarray(faces, dtype=np.int64).reshape(-1, 3)), out)
    return out


@njit(cache=True)
def _crossings(starts, ends, vertices, faces, count, dip):
    buffer_t = np.empty(16)
    buffer_s = np.empty(16)
    for i in range(starts.shape[0]):
        sx, sy, sz = starts[i, 0], starts[i, 1], starts[i, 2]
        dx, dy, dz = ends[i, 0] - sx, ends[i, 1] - sy, ends[i, 2] - sz
        lox, hix = min(sx, ends[i, 0]), max(sx, ends[i, 0])
        loy, hiy = min(sy, ends[i, 1]), max(sy, ends[i, 1])
        loz, hiz = min(sz, ends[i, 2]), max(sz, ends[i, 2])
        n = 0
        for f in range(faces.shape[0]):
            a, b, c = faces[f, 0], faces[f, 1], faces[f, 2]
            ax, ay, az = vertices[a, 0], vertices[a, 1], vertices[a, 2]
            bx, by, bz = vertices[b, 0], vertices[b, 1], vertices[b, 2]
            cx, cy, cz = vertices[c, 0], vertices[c, 1], vertices[c, 2]
            if (max(ax, max(bx, cx)) < lox or min(ax, min(bx, cx)) > hix or max(ay, max(by, cy)) < loy
                    or min(ay, min(by, cy)) > hiy or max(az, max(bz, cz)) < loz or min(az, min(bz, cz)) > hiz):
                continue
            # Moller and Trumbore's ray-triangle test on the segment start + t (end - start), 0 <= t <= 1
            e1x, e1y, e1z = bx - ax, by - ay, bz - az
            e2x, e2y, e2z = cx - ax, cy - ay, cz - az
            px, py, pz = dy * e2z - dz * e2y, dz * e2x - dx * e2z, dx * e2y - dy * e2x
            det = e1x * px + e1y * py + e1z * pz
            if det == 0.0:
                continue
            inv = 1.0 / det
            tx, ty, tz = sx - ax, sy - ay, sz - az
            u = (tx * px + ty * py + tz * pz) * inv
            if u < 0.0 or u > 1.0:
                continue
            qx, qy, qz = ty * e1z - tz * e1y, tz * e1x - tx * e1z, tx * e1y - ty * e1x
            v = (dx * qx + dy * qy + dz * qz) * inv
            if v < 0.0 or u + v > 1.0:
                continue
            t = (e2x * qx + e2y * qy + e2z * qz) * inv
            if t < 0.0 or t > 1.0:
                continue
            if n == buffer_t.shape[0]:
                grown_t, grown_s = np.empty(2 * n), np.empty(2 * n)
                grown_t[:n], grown_s[:n] = buffer_t, buffer_s
                buffer_t, buffer_s = grown_t, grown_s
            buffer_t[n] = t
            # det = -(end - start) . normal: against an outward normal the segment enters the solid
            buffer_s[n] = 1.0 if det > 0.0 else -1.0
            n += 1
        count[i] = n
        lowest, running = 0.0, 0.0
        for k in np.argsort(buffer_t[:n]):
            running += buffer_s[k]
            lowest = min(lowest, running)
        dip[i] = lowest


def segment_crossings(starts: np.ndarray, ends: np.ndarray, vertices: np.ndarray,
                      faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the segments start→end cross the triangles `faces` of `vertices` (an outward-wound surface):
    (P,) int how many triangles each crosses, and (P,) float the lowest the winding number falls along it
    below its value at the start (0 or less: −1 per triangle left through, +1 per one entered, in order)."""
    starts = np.ascontiguousarray(starts, dtype=np.float64).reshape(-1, 3)
    ends = np.ascontiguousarray(ends, dtype=np.float64).reshape(-1, 3)
    count, dip = np.zeros(len(starts), np.int64), np.zeros(len(starts))
    _crossings(starts, ends, np.ascontiguousarray(vertices, dtype=np.float64),
               np.ascontiguousarray(np.asarray(faces, dtype=np.int64).reshape(-1, 3)), count, dip)
    return count, dip


@njit(cache=True, inline="always")
def _segment(px, py, pz, ax, ay, az, bx, by, bz):
    """Distance from p to the segment ab."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    s = (wx * ux + wy * uy + wz * uz) / max(ux * ux + uy * uy + uz * uz, 1e-300)
    s = min(max(s, 0.0), 1.0)
    dx, dy, dz = wx - s * ux, wy - s * uy, wz - s * uz
    return np.sqrt(dx * dx + dy * dy + dz * dz)


@njit(cache=True, inline="always")
def _side(px, py, pz, sx, sy, sz, tx, ty, tz, nx, ny, nz):
    """((t − s) × (p − s)) · n: ≥ 0 when p is on the inner side of the edge st of a triangle with normal n."""
    ex, ey, ez = tx - sx, ty - sy, tz - sz
    wx, wy, wz = px - sx, py - sy, pz - sz
    return (ey * wz - ez * wy) * nx + (ez * wx - ex * wz) * ny + (ex * wy - ey * wx) * nz


@njit(cache=True)
def _triangle_distance(px, py, pz, vertices, a, b, c):
    """Distance from p to the triangle abc (a degenerate one: to its edges)."""
    ax, ay, az = vertices[a, 0], vertices[a, 1], vertices[a, 2]
    bx, by, bz = vertices[b, 0], vertices[b, 1], vertices[b, 2]
    cx, cy, cz = vertices[c, 0], vertices[c, 1], vertices[c, 2]
    ux, uy, uz = bx - ax, by - ay, bz - az
    vx, vy, vz = cx - ax, cy - ay, cz - az
    nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
    nn = nx * nx + ny * ny + nz * nz
    edges = min(min(_segment(px, py, pz, ax, ay, az, bx, by, bz), _segment(px, py, pz, bx, by, bz, cx, cy, cz)),
                _segment(px, py, pz, cx, cy, cz, ax, ay, az))
    if not nn > 0.0:
        return edges
    # the foot of the perpendicular lies within the triangle when it is on the inner side of all three edges
    if (_side(px, py, pz, ax, ay, az, bx, by, bz, nx, ny, nz) < 0.0
            or _side(px, py, pz, bx, by, bz, cx, cy, cz, nx, ny, nz) < 0.0
            or _side(px, py, pz, cx, cy, cz, ax, ay, az, nx, ny, nz) < 0.0):
        return edges
    plane = abs((px - ax) * nx + (py - ay) * ny + (pz - az) * nz) / np.sqrt(nn)
    return min(plane, edges)


@njit(cache=True)
def _distances(points, vertices, faces, out):
    for i in range(points.shape[0]):
        best = np.inf
        for f in range(faces.shape[0]):
            best = min(best, _triangle_distance(points[i, 0], points[i, 1], points[i, 2], vertices,
                                                faces[f, 0], faces[f, 1], faces[f, 2]))
        out[i] = best


def surface_distances(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(P,) the distance from every point to the nearest point of the triangles `faces` of `vertices` (inf
    with no triangles)."""
    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.empty(len(points))
    _distances(points, np.ascontiguousarray(vertices, dtype=np.float64),
               np.ascontiguousarray(np.asarray(faces, dtype=np.int64).reshape(-1, 3)), out)
    return out


@njit(cache=True)
def _nearest_gap(points, vertices, faces, reach_lo, reach_hi, limit):
    plo = np.full(3, np.inf)
    phi = np.full(3, -np.inf)
    for i in range(points.shape[0]):
        for d in range(3):
            plo[d] = min(plo[d], points[i, d])
            phi[d] = max(phi[d], points[i, d])
    best = np.inf
    tlo = np.empty(3)
    thi = np.empty(3)
    for f in range(faces.shape[0]):
        skip = False
        gap2 = 0.0
        for d in range(3):
            x0, x1, x2 = vertices[faces[f, 0], d], vertices[faces[f, 1], d], vertices[faces[f, 2], d]
            tlo[d] = min(x0, min(x1, x2))
            thi[d] = max(x0, max(x1, x2))
            if tlo[d] > reach_hi[d] or thi[d] < reach_lo[d]:
                skip = True
            g = plo[d] - thi[d] if thi[d] < plo[d] else (tlo[d] - phi[d] if tlo[d] > phi[d] else 0.0)
            gap2 += g * g
        # a triangle whose box is farther from the points' box than the gap to beat cannot beat it
        if skip or np.sqrt(gap2) > min(best, limit) * (1.0 + 1e-12):
            continue
        for i in range(points.shape[0]):
            best = min(best, _triangle_distance(points[i, 0], points[i, 1], points[i, 2], vertices,
                                                faces[f, 0], faces[f, 1], faces[f, 2]))
    return best


def nearest_gap(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray, reach_lo: np.ndarray,
                reach_hi: np.ndarray, limit: float) -> float:
    """The least distance from `points` to the triangles `faces` of `vertices` whose boxes overlap the box
    [reach_lo, reach_hi], exact when it is at most `limit` (farther triangles are skipped; inf when none is
    within)."""
    return float(_nearest_gap(np.ascontiguousarray(points, dtype=np.float64),
                              np.ascontiguousarray(vertices, dtype=np.float64),
                              np.ascontiguousarray(np.asarray(faces, dtype=np.int64).reshape(-1, 3)),
                              np.asarray(reach_lo, dtype=np.float64), np.asarray(reach_hi, dtype=np.float64),
                              float(limit)))
