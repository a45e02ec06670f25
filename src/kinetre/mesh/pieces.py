"""A mesh's pieces: its connected parts (a robot's separate limbs, a truck's wheels), each vertex's piece, each
piece's triangles and box, and which piece a part with no bone of its own touches. Computed once per mesh
(`Mesh.pieces`), in time linear in the mesh's size: vertices are welded by position through a hash table and
joined through their faces by union-find.
"""
from __future__ import annotations

import numpy as np

from ..jit import njit
from .solid import nearest_gap, winding_numbers

WELD = 1e-7  # vertices closer than this fraction of the mesh's size are one place
CONTACT = 0.5  # a piece touches another when the gap is within this fraction of its own size
MOST_POINTS = 256  # of a piece's vertices measured for its gap to the others


@njit(cache=True)
def _weld(keys):
    """(V,) int64: the place of every row of `keys` (V, 3) int64, places numbered by first occurrence, and
    their count. Open addressing on a 64-bit mix of the three integers."""
    n = keys.shape[0]
    bits = 4
    while (1 << bits) < 2 * n:
        bits += 1
    mask = (1 << bits) - 1
    table = np.full(mask + 1, -1, np.int64)
    place = np.empty(n, np.int64)
    count = 0
    for v in range(n):
        a, b, c = keys[v, 0], keys[v, 1], keys[v, 2]
        h = (a * np.int64(-7046029254386353131) + b) * np.int64(-4658895280553007687) + c
        h ^= h >> 31
        h *= np.int64(-7723592293110705685)
        h ^= h >> 29
        h &= mask
        while True:
            u = table[h]
            if u < 0:
                table[h] = v
                place[v] = count
                count += 1
                break
            if keys[u, 0] == a and keys[u, 1] == b and keys[u, 2] == c:
                place[v] = place[u]
                break
            h = (h + 1) & mask
    return place, count


@njit(cache=True, inline="always")
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]  # path halving
        i = parent[i]
    return i


@njit(cache=True)
def _components(place, places, faces):
    """(V,) int32 piece per vertex (union-find over the faces' places), pieces numbered by their first vertex,
    and their count."""
    parent = np.arange(places)
    for f in range(faces.shape[0]):
        a = _root(parent, place[faces[f, 0]])
        for k in range(1, 3):
            b = _root(parent, place[faces[f, k]])
            if a != b:
                if b < a:
                    a, b = b, a
                parent[b] = a
    label = np.full(places, -1, np.int64)
    out = np.empty(place.shape[0], np.int32)
    count = 0
    for v in range(place.shape[0]):
        r = _root(parent, place[v])
        if label[r] < 0:
            label[r] = count
            count += 1
        out[v] = label[r]
    return out, count


@njit(cache=True)
def _group(labels, count):
    """Counting sort: (order, start) with group g's indices, ascending, at order[start[g]:start[g + 1]]."""
    start = np.zeros(count + 1, np.int64)
    for i in range(labels.shape[0]):
        start[labels[i] + 1] += 1
    for g in range(count):
        start[g + 1] += start[g]
    fill = start[:-1].copy()
    order = np.empty(labels.shape[0], np.int64)
    for i in range(labels.shape[0]):
        order[fill[labels[i]]] = i
        fill[labels[i]] += 1
    return order, start


@njit(cache=True)
def _boxes(vertices, labels, count):
    lo = np.full((count, 3), np.inf)
    hi = np.full((count, 3), -np.inf)
    for v in range(vertices.shape[0]):
        p = labels[v]
        for d in range(3):
            x = vertices[v, d]
            if x < lo[p, d]:
                lo[p, d] = x
            if x > hi[p, d]:
                hi[p, d] = x
    return lo, hi


def _face_array(faces) -> np.ndarray:
    """(F, 3) contiguous integer faces, as given when they already are (a mesh's int32 ones are not copied)."""
    faces = np.asarray(faces)
    if faces.dtype not in (np.int32, np.int64):
        faces = faces.astype(np.int64)
    return np.ascontiguousarray(faces.reshape(-1, 3))


def connected_pieces(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, int]:
    """((V,) int32, count): the connected component (through faces) of every vertex, numbered by first vertex
    (the piece of vertex 0 is 0). Vertices at one place (within `WELD` of the mesh's size) count as one: a UV or
    normal seam splits a surface's vertices, not the surface."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64)
    if len(vertices) == 0:
        return np.zeros(0, np.int32), 0
    faces = _face_array(faces)
    # welding only joins: a mesh connected through its faces alone is one piece without it
    labels, count = _components(np.arange(len(vertices)), len(vertices), faces)
    if count == 1:
        return labels, count
    lo, hi = (b[0] for b in _boxes(vertices, np.zeros(len(vertices), np.int32), 1))
    size = float((hi - lo).max()) or 1.0
    keys = np.round((vertices - lo) / (WELD * size)).astype(np.int64)
    place, places = _weld(keys)
    return _components(place, places, faces)


class MeshPieces:
    """The pieces of one mesh, computed once (`Mesh.pieces`); read-only.

    Attributes
    ----------
    of_vertex : (V,) int32
        The piece of every vertex (`connected_pieces`).
    count : int
        The number of pieces.
    lo, hi : (count, 3) float64
        The corners of each piece's box.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self._vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        self._faces = _face_array(faces)
        self.of_vertex, self.count = connected_pieces(self._vertices, self._faces)
        self.of_vertex.flags.writeable = False
        self._hosts: dict[int, int] = {}
        if self.count > 1:
            self._vertex_order, self._vertex_start = _group(self.of_vertex, self.count)
            self._face_order, self._face_start = _group(self.of_vertex[self._faces[:, 0]], self.count)
            self.lo, self.hi = _boxes(self._vertices, self.of_vertex, self.count)
        else:  # one piece (or none): its vertices and faces are all of them, in order
            self._vertex_order = self._face_order = None
            self.lo, self.hi = _boxes(self._vertices, self.of_vertex, max(self.count, 1))
        for a in (self.lo, self.hi):
            a.flags.writeable = False

    def scaled(self, factor: float) -> MeshPieces:
        """The same pieces of the mesh scaled by `factor` about the origin (their contacts are the same)."""
        out = object.__new__(MeshPieces)
        out.__dict__.update(self.__dict__)
        out._vertices = self._vertices * factor
        out.lo, out.hi = self.lo * factor, self.hi * factor
        if factor < 0:
            out.lo, out.hi = out.hi, out.lo
        for a in (out.lo, out.hi):
            a.flags.writeable = False
        out._hosts = dict(self._hosts)
        return out

    def vertices_of(self, piece: int) -> np.ndarray:
        """(k,) int64: the vertices of `piece`, ascending."""
        if self._vertex_order is None:
            return np.arange(len(self._vertices)) if piece == 0 else np.zeros(0, np.int64)
        return self._vertex_order[self._vertex_start[piece]:self._vertex_start[piece + 1]]

    def faces_of(self, piece: int) -> np.ndarray:
        """(k, 3) int: the triangles of `piece`, in the mesh's order."""
        if self._face_order is None:
            return self._faces if piece == 0 else self._faces[:0]
        return self._faces[self._face_order[self._face_start[piece]:self._face_start[piece + 1]]]

    def contact_hosts(self, which: np.ndarray) -> np.ndarray:
        """(count,) int: for every piece in `which` (bool per piece) the other piece whose surface comes closest
        to it (the plate a bolt is screwed to, the hand a thumb is part of), -1 for none within CONTACT of the
        piece's own size (it floats) and for the pieces not asked about. Each piece's answer is kept.

        The gap is measured from the piece's vertices to the other pieces' triangles, so a part beside another
        in the bind pose (a thumb raised next to the head) loses to the one it is fixed to."""
        host = np.full(len(which), -1)
        for p in np.flatnonzero(which):
            if p < self.count:
                if p not in self._hosts:
                    self._hosts[int(p)] = self._host(int(p))
                host[p] = self._hosts[int(p)]
        return host

    def _host(self, p: int) -> int:
        lo, hi = self.lo[p], self.hi[p]
        size = float((hi - lo).max())
        mine = self.vertices_of(p)
        mine = mine[np.linspace(0, len(mine) - 1, min(len(mine), MOST_POINTS)).astype(np.int64)]
        points = self._vertices[mine]
        reach_lo, reach_hi = lo - CONTACT * size, hi + CONTACT * size
        near = ~((self.lo > reach_hi).any(axis=1) | (self.hi < reach_lo).any(axis=1))
        near[p] = False
        best, gap = -1, CONTACT * size
        for q in np.flatnonzero(near):
            d = nearest_gap(points, self._vertices, self.faces_of(q), reach_lo, reach_hi, gap)
            if d <= gap:
                best, gap = int(q), d
        return best

    def inside(self, points: np.ndarray) -> np.ndarray:
        """(count, P) bool: each point inside each piece by the winding number of the piece's own triangles
        (≥ 1/2; only points within the piece's box are tested: none outside it can be inside)."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.zeros((self.count, len(points)), bool)
        for p in range(self.count):
            mine = self.faces_of(p)
            if len(mine) == 0:
                continue
            near = np.flatnonzero(((points >= self.lo[p]) & (points <= self.hi[p])).all(axis=1))
            if len(near):
                out[p, near] = winding_numbers(points[near], self._vertices, mine) >= 0.5
        return out
