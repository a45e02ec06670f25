"""How many deformation-graph nodes a mesh gets by default: the paper's 256, or more for a skeleton that
stands where the mesh's artist put it.

Such a skeleton drives the mesh through every bone that moves skin, each carrying the nodes nearest to it
(`attach_skeleton`'s node bones). The paper's 256 nodes serve the Kinect's 19 bones, about 13 a bone, spread
evenly over the surface: a rig's thin parts (a paw, a spider's leg, a tail's tip) then get two or three nodes
and bend only where those sit. An artist's rig gets `PER_BONE` nodes for each of its skinning bones, between
the paper's count and `MOST` (the per-frame solve grows with the nodes).
"""
from __future__ import annotations

from .models import SkeletonModel

DEFAULT = 256
PER_BONE = 24
MOST = 1024


def graph_nodes(standing: SkeletonModel | None) -> int:
    """The default node count: `DEFAULT`, or for a skeleton `standing` inside the mesh `PER_BONE` per bone that
    moves skin, within [DEFAULT, MOST].

    >>> from kinetre.skeleton.models import KINECT20
    >>> graph_nodes(None), graph_nodes(KINECT20)
    (256, 456)
    """
    if standing is None:
        return DEFAULT
    return int(min(MOST, max(DEFAULT, PER_BONE * int(standing.skinning_bones.sum()))))
