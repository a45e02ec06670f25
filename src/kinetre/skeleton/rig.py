"""`attach` once at "possess", `Rig.solve` per frame (the arap_precomputation / arap_solve shape)."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..deform.constraints import PointConstraints
from ..deform.energy import EnergyWeights
from ..deform.normal_equations import NormalEquations
from ..deform.fast.gauss_newton import all_finite
from ..deform.pose import GraphPose
from ..deform.solver import GaussNewton, SolverSettings, SolveReport
from ..errors import AttachError, BadSkeletonError
from ..graph.graph import DeformationGraph
from ..mesh.mesh import Mesh
from .attach import SkeletonAttachment, StackedAttachments, attach_skeleton, stacked_targets
from .models import Skeleton
from .rigid_pieces import hold_rigid, rigid_pieces
from .subsets import subset_mask


_NO_FRAMES = np.zeros((0, 3, 3))  # frames without source bone frames: bones turn by their directions
REACH, BONE_RADIUS = 0.10, 0.04  # metres: how near the mesh a joint attaches, and a bone's cylinder (people)


def _as_list(skeletons) -> list[Skeleton]:
    if isinstance(skeletons, Skeleton):
        return [skeletons]
    out = list(skeletons)
    if not all(isinstance(s, Skeleton) for s in out):
        raise BadSkeletonError("expected a Skeleton or a list of Skeletons")
    return out


class Rig:
    """A mesh's graph possessed by one or more skeletons.

    Holds what is fixed from the moment of possession (constraints, normal-equation pattern and its
    symbolic factorisation) and the last good pose for warm starts and tracking loss.

    Attributes
    ----------
    graph : DeformationGraph
    attachments : tuple of SkeletonAttachment, one per skeleton
    last_report : SolveReport or None, the most recent solve's details
    rigid_pieces : tuple of RigidPiece, the mesh pieces that follow one bone rigidly (with `rigid`; else
        none: every node is the solve's)
    """

    def __init__(self, graph: DeformationGraph, attachments: Sequence[SkeletonAttachment],
                 weights: EnergyWeights = EnergyWeights(), settings: SolverSettings = SolverSettings(),
                 backend: str | None = None, rigid: bool = False):
        self.graph = graph
        self.attachments = tuple(attachments)
        self.weights = weights
        self.constraints = PointConstraints.concatenate([a.constraints for a in self.attachments])
        bridges = graph.edges[graph.bridges]
        self.system = NormalEquations.build(graph.nodes, graph.edges, bridges, self.constraints, weights)
        self.solver = GaussNewton(self.system, settings, backend)
        # per frame the skeletons' joints are stacked and every target moved by one numba call into buffers
        # of the rig (`stacked_targets`)
        self._stacked = StackedAttachments.of(self.attachments)
        self._q = np.zeros((len(self.constraints), 3))
        self._active = np.zeros(len(self.constraints))
        self._x = np.zeros((graph.node_count, 12))
        self._x[:, [0, 4, 8]] = 1.0
        self._x_before: np.ndarray | None = None  # the pose one solve earlier, for a constant-velocity guess
        self.rigid_pieces = rigid_pieces(graph.pieces, self.attachments) if rigid else ()
        self.last_report: SolveReport | None = None

    @property
    def constraint_count(self) -> int:
        return len(self.constraints)

    @property
    def attached_joints(self) -> list[np.ndarray]:
        """Per skeleton, the indices of its joints that attached."""
        return [a.joint[a.joint >= 0] for a in self.attachments]

    @property
    def nodes_used(self) -> np.ndarray:
        """Indices of graph nodes that carry at least one constraint."""
        return np.unique(self.constraints.nodes[self.constraints.weights > 0])

    @property
    def pose(self) -> GraphPose:
        """The last good pose (identity before the first solve)."""
        return self._pose_of(self._x, float("nan"), 0)

    def _pose_of(self, x, energy, iterations) -> GraphPose:
        return GraphPose(x[:, :9].reshape(-1, 3, 3).copy(), x[:, 9:].copy(), energy, iterations)

    def reset(self) -> None:
        """Back to the rest pose (identity transforms)."""
        self._x[:] = 0.0
        self._x[:, [0, 4, 8]] = 1.0
        self._x_before = None

    def targets(self, skeletons) -> tuple[np.ndarray, np.ndarray]:
        """Constraint targets (L, 3) and active mask (L,) for the current frame of every skeleton."""
        q, active, _ = self._targets(skeletons)
        return q.copy(), active > 0.0

    def _targets(self, skeletons) -> tuple[np.ndarray, np.ndarray, int]:
        """`targets` into the rig's buffers (overwritten next frame), the mask as the solver's (L,) scales,
        and the number of tracked constraints."""
        frames = _as_list(skeletons)
        if len(frames) != len(self.attachments):
            raise BadSkeletonError(f"the rig was attached to {len(self.attachments)} skeleton(s), "
                                   f"got {len(frames)} frame(s)")
        for att, frame in zip(self.attachments, frames):
            if frame.model is not att.bind.model and frame.model != att.bind.model:
                raise BadSkeletonError(f"frame has skeleton model {frame.model.name!r}, "
                                       f"the rig was attached with {att.bind.model.name!r}")
        if len(frames) == 1:
            positions, tracked = np.ascontiguousarray(frames[0].positions), frames[0].tracked
        else:
            positions = np.concatenate([f.positions for f in frames])
            tracked = np.concatenate([f.tracked for f in frames])
        st = self._stacked
        bone_frames = _NO_FRAMES
        if st.framed and any(f.bone_frames is not None for f in frames):
            bone_frames = np.concatenate([np.full((len(f.model.joints), 3, 3), np.nan) if f.bone_frames is None
                                          else f.bone_frames for f in frames])
        count = stacked_targets(st.bind, st.bones, st.parent_bone, st.twist_reference, st.joint, st.bone, st.offset,
                                st.points, positions, tracked, self._q, self._active, st.bind_frames, bone_frames)
        return self._q, self._active, count

    def solve(self, skeletons, stop=None) -> GraphPose:
        """Deform the graph so the attached joints and bones follow the current frame(s).

        Warm-starts from the previous pose, or from the pose extrapolated at constant velocity from the
        last two when that fits the new targets better (fewer iterations on smooth motion). Untracked joints and bones drop out of E_con for this
        frame; with nothing tracked, or a non-finite result, the last good pose is returned. `stop`: see
        `GaussNewton.solve` (a live solve passes "is a newer frame waiting?").
        """
        q, active, count = self._targets(skeletons)
        if not count:
            return self._pose_of(self._x, float("nan"), 0)
        report = self.solver.solve(self._x, q, active, stop=stop, before=self._x_before)
        self.last_report = report
        if not all_finite(report.x):
            return self._pose_of(self._x, float("nan"), 0)
        x = report.x
        if self.rigid_pieces:
            x = hold_rigid(x, self.graph.nodes, self.rigid_pieces, self.attachments, _as_list(skeletons))
        self._x_before, self._x = self._x, x
        return self._pose_of(self._x, report.energy, report.iterations)


def attach(graph: DeformationGraph, skeletons, subset=None, reach=REACH, bone_radius=BONE_RADIUS,
           weights: EnergyWeights = EnergyWeights(), settings: SolverSettings = SolverSettings(),
           backend: str | None = None, node_bones: bool = False, rigid: bool = False,
           mesh: Mesh | None = None) -> Rig:
    """Possess the graph with one or more skeletons in their current (bind) pose.

    Parameters
    ----------
    graph : DeformationGraph, in the skeletons' frame and units (metres, +Y up)
    skeletons : Skeleton or list of Skeleton (two users can drive one horse)
    subset : joint subset for every skeleton ("left arm", ["HipCenter", "right arm"], None = whole
        body), or a list with one subset per skeleton
    reach : attachment distance, 10 cm; bone_radius : bone cylinder radius, 4 cm; either may be a list with
        one value per skeleton (a hand puppet scaled up into a mesh reaches as far as its fit scaled it)
    node_bones : every graph node also follows its nearest bone (a skeleton that stands where the mesh's
        artist put it: `attach_skeleton`)
    rigid : a separate piece of the mesh whose bone samples come from one bone follows that bone rigidly
        (`rigid_pieces`)
    mesh : the graph's mesh in the same frame, if at hand: with `node_bones`, which bones run through each of
        its pieces is then told from the piece's own triangles (`piece_bones`)

    Raises
    ------
    AttachError
        When no joint or bone sample of any skeleton lies within `reach` of the graph.
    """
    frames = _as_list(skeletons)
    if not frames:
        raise BadSkeletonError("attach needs at least one skeleton")
    if isinstance(subset, list) and len(subset) == len(frames) and len(frames) > 1 and \
            all(s is None or isinstance(s, (str, list, tuple)) for s in subset) and \
            not all(isinstance(s, str) for s in subset):
        subsets = subset
    else:
        subsets = [subset] * len(frames)
    reaches = list(reach) if isinstance(reach, (list, tuple)) else [reach] * len(frames)
    radii = list(bone_radius) if isinstance(bone_radius, (list, tuple)) else [bone_radius] * len(frames)
    if len(reaches) != len(frames) or len(radii) != len(frames):
        raise BadSkeletonError(f"{len(frames)} skeleton(s) but {len(reaches)} reach(es) and {len(radii)} bone radii")
    atts = [attach_skeleton(graph, f, subset_mask(f.model, s), r, b, node_bones, mesh)
            for f, s, r, b in zip(frames, subsets, reaches, radii)]
    if sum(len(a.constraints) for a in atts) == 0:
        tracked = np.concatenate([f.positions[f.tracked] for f in frames])
        if len(tracked) == 0:
            raise AttachError("cannot possess: no joint of the skeleton is tracked")
        from scipy.spatial import cKDTree
        d, _ = cKDTree(graph.nodes).query(tracked)
        raise AttachError(
            f"cannot possess: no joint or bone is within {max(reaches) * 100:.0f} cm of the mesh (nearest joint "
            f"is {d.min():.2f} m away); step into the mesh, move it, or scale it to your height")
    return Rig(graph, atts, weights, settings, backend, rigid)
