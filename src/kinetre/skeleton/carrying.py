"""Which bone carries each graph node of a mesh whose artist's skeleton stands inside it (`attach_skeleton`'s
node bones).

The nearest bone is a poor guide where parts of the body press together: a quadruped caught mid-gallop has
its legs swung under the belly, the upper leg bones run inside the torso, and the belly lies nearer to a leg
than to the spine. So, as in Baran and Popović's bone heat ("Automatic Rigging and Animation of 3D
Characters", SIGGRAPH 2007, §4: a vertex binds to the nearest bone it can see from inside the mesh):

1. a node takes the nearest bone it can see through the inside of the mesh without crossing another surface
   (the way starts inside and crosses no triangle: from the belly, a leg bone inside the torso lies behind
   the leg's own skin); failing that, one it reaches through the inside, crossings allowed;
   failing that, the nearest; a bone seen is taken only within a few times the nearest's distance (beyond,
   a seam of the surface is likelier than a hidden bone);
2. distance past either end of a bone counts double: a node beside a joint belongs to the bone that runs
   past it, not to the one that stops short of it;
3. a node whose skin lies inside another part of its own piece (a leg's skin pushed into the chest, found by
   the winding number just outside it) cannot tell its bone from where it is: it takes the bone most of its
   graph neighbours on the piece have, from the nodes that can;
4. a node then takes the bone held by more than half of itself and its graph neighbours on its piece, so a
   lone node does not follow a part it merely touches.

As in 1, in 3 and 4 a node takes only a bone within FARTHEST times its nearest's distance: a coarse graph's
edges can reach from a hand to the shoulder, and a neighbour's bone that far away cannot carry it.
"""
from __future__ import annotations

import numpy as np

from ..graph.graph import DeformationGraph
from ..mesh.mesh import Mesh
from ..mesh.solid import segment_crossings, winding_numbers
from .models import Skeleton

PAST_END = 2.0  # weight of the distance along a bone beyond either of its ends
START = 0.1  # share of the way skipped next to the node (its own skin)
FARTHEST = 3.0  # a bone seen from a node may cost at most this many times its cheapest
OUTSIDE = 0.005  # of the mesh's longest side: how far outside its skin a node's surroundings are tested
PER_PATH = 2  # point-triangle pairs a way costs: its start's winding number, and its crossings (as cheap)
BUDGET = 6e7  # point-triangle pairs, at most (about 2 s; a first try beyond it: the nearest bone)


def carrying_bones(graph: DeformationGraph, skeleton: Skeleton, joint_mask: np.ndarray, mesh: Mesh,
                   allowed: np.ndarray | None = None) -> np.ndarray:
    """(N,) int: per graph node the row in model.bones of the bone that carries it, or -1 where none may.

    Parameters
    ----------
    graph : DeformationGraph, in the skeleton's frame
    skeleton : Skeleton, the bind pose (standing inside the mesh)
    joint_mask : (J,) bool, the joints that may carry; a bone needs both of its joints
    mesh : Mesh, the graph's mesh in the same frame
    allowed : (N, B) bool or None, the bones each node may take
    """
    nodes = graph.nodes
    bones = np.asarray(skeleton.model.bones, dtype=np.int64).reshape(-1, 2)
    pos = skeleton.positions
    ok = joint_mask[bones[:, 0]] & joint_mask[bones[:, 1]]
    ok &= np.linalg.norm(pos[bones[:, 1]] - pos[bones[:, 0]], axis=1) > 1e-9
    out = np.full(len(nodes), -1)
    if not ok.any() or len(nodes) == 0:
        return out
    rows = np.flatnonzero(ok)
    cost, closest = bone_costs(nodes, pos[bones[rows, 0]], pos[bones[rows, 1]])
    if allowed is not None:
        cost = np.where(allowed[:, rows], cost, np.inf)
    order = np.argsort(cost, axis=1)
    has = np.isfinite(cost[np.arange(len(nodes)), order[:, 0]])
    best = order[:, 0].copy()
    faces = np.asarray(mesh.faces).reshape(-1, 3)
    if len(nodes) * (PER_PATH + 1) * len(faces) > BUDGET:  # too big a mesh to look through: the nearest bone
        nearest = np.linalg.norm(nodes[:, None] - closest, axis=2)
        nearest = np.where(np.isfinite(cost), nearest, np.inf).argmin(axis=1)
        return np.where(has, rows[nearest], -1)
    # the bones near enough to carry each node, seen (1) or taken from neighbours (3, 4)
    near = np.zeros(cost.shape, bool)
    near[has] = cost[has] <= FARTHEST * cost[has, order[has, 0]][:, None]
    label = _visible_bones(nodes, closest, near, order, mesh.vertices, faces)
    size = float(np.max(np.ptp(mesh.vertices, axis=0))) if len(mesh.vertices) else 0.0
    buried = _buried(nodes + OUTSIDE * size * graph.normals, graph, mesh)
    neighbours = graph.neighbours()
    if graph.pieces is not None and len(graph.pieces) == len(nodes):  # a piece's bones come from its own nodes
        neighbours = [n[graph.pieces[n] == graph.pieces[i]] for i, n in enumerate(neighbours)]
    label = _from_neighbours(label, ~buried & has, neighbours, near)
    label = _majority(label, neighbours, has, near)
    if allowed is not None:  # a neighbour's bone may be one this node's piece may not take
        label = np.where(allowed[np.arange(len(nodes)), rows[label]], label, best)
    return np.where(has, rows[label], -1)


def bone_costs(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(P, B) distance from every point to every bone a→b with the part along the bone beyond its ends weighted
    by PAST_END, and (P, B, 3) the closest points on the bones."""
    ab = b - a
    length2 = np.einsum("bi,bi->b", ab, ab)
    s = np.einsum("pbi,bi->pb", points[:, None] - a[None], ab) / length2
    inside = np.clip(s, 0.0, 1.0)
    closest = a[None] + inside[..., None] * ab[None]
    radial = np.linalg.norm(points[:, None] - (a[None] + s[..., None] * ab[None]), axis=2)
    along = np.abs(s - inside) * np.sqrt(length2)[None]
    return np.sqrt(radial ** 2 + (PAST_END * along) ** 2), closest


def _visible_bones(nodes, closest, near, order, vertices, faces) -> np.ndarray:
    """(N,) column of `order`'s costs per node: its cheapest bone seen without crossing a surface, else the
    cheapest reached through the inside, else the cheapest. Bones are tried cheapest first, only those `near`
    the node ((N, B) bool), each node's only until one is seen clearly, within BUDGET point-triangle pairs."""
    n = len(nodes)
    clear = np.full(n, -1)
    through = np.full(n, -1)
    pending = np.arange(n)
    spent = 0
    for k in range(order.shape[1]):
        col = order[pending, k]
        live = near[pending, col]
        pending, col = pending[live], col[live]
        spent += len(pending) * PER_PATH * len(faces)
        if not len(pending) or (k and spent > BUDGET):
            break
        start = nodes[pending] + START * (closest[pending, col] - nodes[pending])
        # the winding number where the way starts, then its changes at each surface the way crosses
        wn = winding_numbers(start, vertices, faces)
        crossed, dip = segment_crossings(start, closest[pending, col], vertices, faces)
        seen = (wn > 0.5) & (crossed == 0)
        inside = wn + dip > 0.5
        clear[pending[seen]] = col[seen]
        first = inside & (through[pending] < 0)
        through[pending[first]] = col[first]
        pending = pending[~seen]
    return np.where(clear >= 0, clear, np.where(through >= 0, through, order[:, 0]))


def _buried(outside: np.ndarray, graph: DeformationGraph, mesh: Mesh) -> np.ndarray:
    """(N,) bool: each node's point just outside its skin lies inside its own piece of the mesh. A part the
    artist built as a separate piece pushed into another (a capsule limb in a body) is carried by the bones
    running through it (`piece_bones`), so only skin folded into its own surface counts."""
    pieces = graph.pieces
    if pieces is None or len(pieces) != len(outside) or mesh.pieces.count < 2:
        return winding_numbers(outside, mesh.vertices, mesh.faces) > 0.5
    out = np.zeros(len(outside), bool)
    for p in np.unique(pieces):
        mine = np.flatnonzero(pieces == p)
        faces = mesh.pieces.faces_of(int(p))
        if len(faces):
            out[mine] = winding_numbers(outside[mine], mesh.vertices, faces) > 0.5
    return out


def _from_neighbours(label: np.ndarray, known: np.ndarray, neighbours: list[np.ndarray],
                     near: np.ndarray) -> np.ndarray:
    """`label` with every node not `known` given the label most of its known neighbours hold among the bones
    `near` it ((N, B) bool), spreading out from the known nodes ring by ring (a node no known node reaches, or
    whose known neighbours hold no bone near it, keeps its own)."""
    label, known = label.copy(), known.copy()
    while True:
        todo = [i for i in np.flatnonzero(~known) if known[neighbours[i]].any()]
        if not todo:
            return label
        new = {}
        for i in todo:
            held = label[neighbours[i][known[neighbours[i]]]]
            held = held[near[i, held]]
            new[i] = _most(held) if held.size else label[i]
        for i, value in new.items():
            label[i] = value
            known[i] = True


def _majority(label: np.ndarray, neighbours: list[np.ndarray], has: np.ndarray, near: np.ndarray) -> np.ndarray:
    """Every node with the label held by more than half of itself and its neighbours, where one is and it is a
    bone `near` the node."""
    out = label.copy()
    for i in np.flatnonzero(has):
        ring = np.append(label[neighbours[i]], label[i])
        values, counts = np.unique(ring, return_counts=True)
        top = values[np.argmax(counts)]
        if 2 * counts.max() > len(ring) and near[i, top]:
            out[i] = top
    return out


def _most(values: np.ndarray) -> int:
    found, counts = np.unique(values, return_counts=True)
    return int(found[np.argmax(counts)])
