"""A mesh driven by a take, end to end: graph, placement, attachment, one solve per frame.

    >>> import kinetre
    >>> mesh = kinetre.load_mesh("chair.obj")                                  # doctest: +SKIP
    >>> take = kinetre.load_take("walk.bvh")                                   # doctest: +SKIP
    >>> result = kinetre.animate(mesh, take, kinetre.AnimateSettings(nodes=256))  # doctest: +SKIP
    >>> vertices = kinetre.skin(result.mesh, result.graph, result.poses[10])  # doctest: +SKIP

`kinetre animate` is this call with the file reading and writing around it.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .deform.energy import CARRIED, EnergyWeights
from .deform.pose import GraphPose
from .errors import BadSettingsError
from .graph.graph import DeformationGraph
from .mesh.mesh import Mesh
from .motion.fit import Placement
from .motion.take import Take
from .skeleton.node_budget import graph_nodes
from .skeleton.rig import Rig
from .stopwatch import Stopwatch

if TYPE_CHECKING:
    from .mesh.upright import Upright
    from .preprocessed import MeshCache

FITS = (None, "mesh", "height", "length")
SOLVERS = (None, "pcg", "exact")
UPS = ("auto", "y", "z", "x", "-x", "-y", "-z")  # "auto" and kinetre.mesh.upright.AXES, kept unloaded


@dataclass(frozen=True)
class AnimateSettings:
    """How `animate` rigs and solves.

    Attributes
    ----------
    nodes : deformation-graph nodes (None: 256, more for a skeleton standing where the mesh's artist put
        it: `kinetre.skeleton.node_budget`); seed : their sampling seed
    subset : joint names or subset names that drive (None: every joint)
    bind_frame : the take's frame that is the bind (rest) pose
    solver : per-frame solver ("pcg", "exact"; None: the library's default)
    fit : None (the motion is sized to the mesh), "mesh" (the mesh is resized to the skeleton in the
        output), "height" or "length" (size a non-human source to the mesh by that extent)
    yaw : degrees about +Y the skeleton is turned (people: from the mesh front +Z; other skeletons: added
        to the facing found from the shapes); flip : turn it round
    solve : solve every frame and skin the graph (False: only place the skeleton, for skeleton outputs)
    up : the mesh's up axis: "auto" (+Y up when the source's skeleton stands inside it as stored; else
        glTF/VRM are +Y up by spec and other meshes stand on the axis found from their shape,
        `kinetre.mesh.upright`), or the stored axis to turn up: "y" (as stored), "z", "x", "-x", "-y", "-z"
    hang : a hand (`HAND21`) is turned first so its fingertips hang below its palm in the bind frame, its
        fingers the mesh's legs (False: fitted as held)
    """

    nodes: int | None = None
    seed: int = 0
    subset: str | tuple[str, ...] | None = None
    bind_frame: int = 0
    solver: str | None = None
    fit: str | None = None
    yaw: float | None = None
    flip: bool = False
    solve: bool = True
    up: str = "auto"
    hang: bool = True

    def __post_init__(self):
        """A setting no input can use is refused here, when it is made (BadSettingsError)."""
        if self.nodes is not None and (isinstance(self.nodes, bool) or not isinstance(self.nodes, int)
                                       or self.nodes < 2):
            raise BadSettingsError(f"--nodes must be an integer of at least 2, got {self.nodes!r}")
        if self.fit not in FITS:
            raise BadSettingsError(f"fit must be one of mesh, height, length or None, got {self.fit!r}")
        if self.solver not in SOLVERS:
            raise BadSettingsError(f"solver must be one of pcg, exact or None, got {self.solver!r}")
        if self.up not in UPS:
            raise BadSettingsError(f"--up must be one of {', '.join(UPS)}, got {self.up!r}")
        if isinstance(self.bind_frame, bool) or not isinstance(self.bind_frame, int):
            raise BadSettingsError(f"--bind-frame must be an integer, got {self.bind_frame!r}")


@dataclass(frozen=True)
class Animation:
    """What `animate` made.

    Attributes
    ----------
    mesh : the mesh stood +Y up, in the output's units (resized to the skeleton with `fit="mesh"`)
    graph : its deformation graph with skinning weights (without them when nothing was solved)
    poses : one GraphPose per take frame, in the output's units (empty when nothing was solved)
    take : the placed skeleton in the output's units, one frame per pose
    placement : where the take went relative to the mesh (`Placement.method`: how it was found)
    rig : the possessed graph (in the solve frame)
    shape_fit : the shapes' fit for a non-human source (None for a person)
    notes : warnings in words about a poor match
    seconds : wall and CPU seconds per stage ("graph_s", "graph_cpu", "attach_s", ..., "weights_cpu")
    upright : the up axis the mesh was taken with and why (`mesh` is the input turned by
        `kinetre.mesh.upright.rotation_to_y_up(upright.up)` before any resizing)
    """

    mesh: Mesh
    graph: DeformationGraph
    poses: tuple[GraphPose, ...]
    take: Take
    placement: Placement
    rig: Rig
    shape_fit: object | None
    notes: tuple[str, ...]
    seconds: dict
    upright: Upright


def animate(mesh: Mesh, take: Take, settings: AnimateSettings = AnimateSettings(),
            on_frame: Callable[[int], None] | None = None,
            on_step: Callable[[str], None] | None = None, kept: MeshCache | None = None) -> Animation:
    """Drive `mesh` with every frame of `take`.

    Parameters
    ----------
    mesh : Mesh (any units); stood +Y up first as `settings.up` says, and driven and returned that way
    take : Take, +Y up (a Kinect-20 person is fitted by height; any other skeleton from the two shapes)
    settings : AnimateSettings
    on_frame : called with each frame's index once it is solved (progress)
    on_step : called with "graph", "placement", "attach" as each rigging step ends (progress)
    kept : the mesh file's kept preprocessing (`kinetre.preprocessed`): the up axis its shape stands on and
        its graph with weights for these settings are taken from there when kept, else found and kept there

    Raises
    ------
    BadSettingsError
        A setting that does not fit the input (a bind frame outside the take, a size fit for a person).
    BadMotionError, AttachError, BadGraphError
        The take cannot be placed, nothing of it lies near the mesh, or the graph cannot be built.
    """
    import kinetre
    from .deform.solver import SolverSettings
    from .mesh.upright import turned
    from .motion.fit import fit_take
    from .motion.in_place import in_place

    s = settings
    if not -len(take) <= s.bind_frame < len(take):
        raise BadSettingsError(f"--bind-frame {s.bind_frame} is outside the take's {len(take)} frames")
    step = on_step or (lambda name: None)
    watch = Stopwatch()
    seconds, lap = watch.seconds, watch.lap

    upright = _upright(mesh, take, s, kept)
    mesh = turned(mesh, upright.up)
    standing = _standing_source(take, mesh, s)
    nodes = s.nodes if s.nodes is not None else graph_nodes(None if standing is None else standing.model)
    graph = kept.graph(upright.up, nodes, s.seed) if kept is not None and s.solve else None
    weighing = None
    if graph is None:
        graph = kinetre.build_graph(mesh, nodes=nodes, seed=s.seed, weights=False)
        # the skinning weights (only a solved animation needs them) are computed on another core meanwhile
        keep = (lambda g: kept.keep_graph(g, upright.up, nodes, s.seed)) if kept is not None else None
        weighing = _weigh_in_background(graph, mesh, keep) if s.solve else None
    step("graph")
    lap("graph")
    fit_mesh = s.fit == "mesh"
    shape = None
    if standing is not None:  # the source already stands inside the mesh: all its bones, where they are
        take, fit_mesh = standing, False
        placement, notes = in_place(mesh), ()
    elif take.model == kinetre.KINECT20:  # a person: face +Z, scale to height
        if s.fit in ("height", "length"):
            raise BadSettingsError("--fit height|length applies to non-human skeletons (people are fitted by "
                                   "height)")
        yaw = (s.yaw or 0.0) + (180.0 if s.flip else 0.0)
        placement = fit_take(take, mesh, s.bind_frame, fit_mesh=fit_mesh, yaw=yaw)
        notes: tuple[str, ...] = ()
    else:  # any other skeleton: from the two shapes (a hand turned to hang by its fingers first)
        from .motion.align import fit_shapes
        from .motion.hands import fit_hand
        options = {"fit": s.fit if s.fit in ("height", "length") else "auto", "yaw": s.yaw or 0.0,
                   "flip": s.flip, "fit_mesh": fit_mesh, "nodes": graph.nodes}
        if take.model == kinetre.HAND21:
            shape = fit_hand(take, mesh, s.bind_frame, hang=s.hang, **options)
        else:
            shape = fit_shapes(take, mesh, s.bind_frame, **options)
        placement, notes = shape.placement, tuple(shape.notes)
    step("placement")
    placed = placement.take(take)
    solve_graph = placement.graph(graph)
    bind = placed.frame(s.bind_frame)
    solver = SolverSettings() if s.solver is None else SolverSettings(method=s.solver)
    subset = list(s.subset) if isinstance(s.subset, tuple) else s.subset
    in_place = placement.method == "in place"
    rig = kinetre.attach(solve_graph, bind, subset=subset, settings=solver, node_bones=in_place, rigid=True,
                         weights=CARRIED if in_place else EnergyWeights(), mesh=placement.mesh(mesh))
    step("attach")
    notes = notes + _attach_notes(take, rig, s.subset)
    lap("attach")

    out_take = placed.transformed(placement.output_scale)
    poses: list[GraphPose] = []
    mesh_out = placement.mesh(mesh) if fit_mesh else mesh
    if s.solve:
        for i in range(len(placed)):
            poses.append(placement.output_pose(rig.solve(placed.frame(i))))
            if on_frame is not None:
                on_frame(i)
        lap("solve")
        wait = time.perf_counter()
        seconds["weights_cpu"] = 0.0  # a kept graph comes with its weights
        if weighing is not None:
            graph, seconds["weights_cpu"] = weighing.result()
        seconds["weights_wait_s"] = time.perf_counter() - wait
    graph_out = placement.graph(graph) if fit_mesh else graph
    return Animation(mesh_out, graph_out, tuple(poses), out_take, placement, rig, shape, notes, seconds, upright)


def _upright(mesh: Mesh, take: Take, s: AnimateSettings, kept: MeshCache | None = None) -> Upright:
    """The up axis `mesh` is driven with: the one asked, else found from its file (`mesh.source`) and shape
    (or kept from an earlier run in `kept`). A +Z up found from the shape gives way when the take's own
    skeleton (a take is +Y up) stands inside the mesh as stored: a figure on rounded feet may topple by the
    floor test, yet it stands."""
    from .mesh.upright import Upright, axis_name, find_upright
    from .motion.in_place import stands_inside

    if s.up != "auto":
        return Upright(s.up, {}, f"{axis_name(s.up)} up, as asked")
    found = kept.upright(mesh.source) if kept is not None else None
    if found is None:
        found = find_upright(mesh, mesh.source)
        if kept is not None:
            kept.keep_upright(mesh.source, found)
    if found.up != "y" and stands_inside(take.native if take.native is not None else take, mesh, s.bind_frame):
        return Upright("y", found.scores, "+Y up: the motion's skeleton stands inside it as stored")
    return found


def _standing_source(take: Take, mesh: Mesh, s: AnimateSettings) -> Take | None:
    """The take to drive with where it stands when the source already lies inside the mesh (its own
    skeleton when it was mapped to Kinect-20), else None. A placement asked for (a turn, a size fit, a joint
    subset named on the mapped skeleton) keeps the fitting path."""
    from .motion.in_place import stands_inside
    from .skeleton.models import KINECT20

    if s.yaw is not None or s.flip or s.fit is not None or s.subset is not None:
        return None
    source = take.native if take.native is not None else take if take.model != KINECT20 else None
    if source is None or not stands_inside(source, mesh, s.bind_frame):
        return None
    return source


def _weigh_in_background(graph, mesh, keep=None):
    """A future of (`graph` with `mesh`'s skinning weights, the CPU seconds they took), computed in a thread:
    the weights kernels release the GIL, so on a machine with a free core they cost no time beside the
    attach and solve. `keep`, if given, is then called
    with the weighted graph in the thread (to write it to the cache meanwhile too)."""
    from concurrent.futures import ThreadPoolExecutor

    from .graph.build import with_weights
    from .graph.weights import skinning_weights

    def weigh():
        cpu = time.thread_time()
        weighted = with_weights(graph, mesh)
        cpu = time.thread_time() - cpu
        if keep is not None:
            keep(weighted)
        return weighted, cpu

    # load the kernels here first: the thread then runs compiled code only, never numba's compiler or an
    # import, which the main thread may be doing at the same time
    skinning_weights(mesh.vertices[:1], mesh.normals[:1], graph.nodes, graph.normals, graph.radius)
    pool = ThreadPoolExecutor(1, thread_name_prefix="kinetre-weights")
    future = pool.submit(weigh)
    pool.shutdown(wait=False)  # the thread ends with its one task
    return future


def _attach_notes(take, rig, subset) -> tuple[str, ...]:
    """Words for a poor attachment: few of the (wanted) joints within reach of the mesh."""
    if subset:
        return ()
    wanted = len(take.model.joints)
    got = len(rig.attached_joints[0])
    if got >= 0.5 * wanted:
        return ()
    return (f"only {got} of {wanted} joints lie within reach of the mesh: try --yaw 90, --flip, "
            f"--fit height|length or more --nodes",)
