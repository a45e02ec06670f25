"""RGB-D frames in, a clean mesh ready to possess out: track, fuse, segment, marching cubes, clean, write.

    >>> from kinetre.scan.pipeline import scan                     # doctest: +SKIP
    >>> result = scan("frames/", "chair.ply", segment="plane")       # doctest: +SKIP
    >>> print(result.summary())                                     # doctest: +SKIP
    scan: 120 frames used, 3 rejected, 20412 vertices, 40110 faces, 95.2 s -> chair.ply
"""
from __future__ import annotations

import io
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import BadScanError, ExportError
from ..rotation import minimal_rotations
from .depth_reading import DepthReading, depth_reading, sample_depths, size_warning
from .frames import Intrinsics, RGBDSequence, open_sequence, read_frame
from .features import Features, frame_features
from .fuse import TSDFVolume
from .loop import MAX_KEYFRAMES, Edge, information, loop_edges, optimise
from .segment import (SPECK_JOINS, changed_voxels, cut_above_plane, cut_to_voxels, dominant_plane, focus_point,
                      remove_floaters, select_object)
from .surface import CAMERA_TO_Y_UP, MESH_SUFFIXES, ScanMesh, decimate, orient_outward, write_mesh
from .recent import RecentFrames
from .track import TrackingParams, dense_motion, track_frame

SEGMENTS = (None, "plane", "change")
# pieces closer than this many voxels are one object: a thin part can fuse with a gap of a voxel or two
JOIN_VOXELS = 2.0
MAX_VIEWS = 60  # depth frames kept per sweep to tell seen-empty space from unseen space in change detection


@dataclass(frozen=True)
class ScanResult:
    """What a scan produced.

    mesh_path : the written mesh; frames_used / frames_rejected : counts over all sequences
    vertices, faces : size of the written mesh; seconds : wall time
    poses : (N, 4, 4) float64 camera-to-world pose of every frame of the main sequence (world = the first
            camera, of the `before` sweep when there is one; rejected frames hold the pose tracking proposed)
    accepted : (N,) bool, the frames that were fused
    transform : (4, 4) float64 from world (camera axes, y down) to the written mesh's frame (+Y up)
    report : lines for the terminal saying where the surface went: the depths read and the scale that gave
             them, frames used and rejected (why), voxels fused, components found and their sizes, which one
             was kept and why
    depth : the depths read from the main sequence (depth_reading.py)
    warnings : lines for stderr: results that do not fit what was read (a kept object too small for the
             depths, see depth_reading.py)
    """

    mesh_path: Path
    frames_used: int
    frames_rejected: int
    vertices: int
    faces: int
    seconds: float
    poses: np.ndarray = field(repr=False)
    accepted: np.ndarray = field(repr=False)
    transform: np.ndarray = field(repr=False)
    report: tuple = ()  # lines saying what was kept and why: frames, fusion, components
    depth: DepthReading | None = None
    warnings: tuple = ()

    def summary(self) -> str:
        """One line for the terminal."""
        return (f"scan: {self.frames_used} frames used, {self.frames_rejected} rejected, {self.vertices} vertices, "
                f"{self.faces} faces, {self.seconds:.1f} s -> {self.mesh_path}")


@dataclass
class _Fused:
    poses: list
    accepted: list
    first_view: np.ndarray | None  # (N, 3) world points of the first accepted frame
    views: list  # (depth, pose, camera) of up to MAX_VIEWS accepted frames, for change detection
    rejected: list = field(default_factory=list)  # (frame index, reason)
    fitness: list = field(default_factory=list)  # agreement of each tracked, accepted frame with the model
    loops: int = 0  # loop closures that survived the pose-graph optimisation
    moved: float = 0.0  # largest change of a camera position by the optimisation (metres)
    closing_cpu: float = 0.0  # CPU seconds of loop closure and the second fusion (the rest is per frame)
    tracked: list = field(default_factory=list)  # the poses as tracked, before loop closure moved them
    depths: list = field(default_factory=list)  # sample_depths of every frame read


def fuse_sequence(sequence: RGBDSequence, volume: TSDFVolume, params: TrackingParams, *,
                  tracking_model: TSDFVolume | None = None, guesses: tuple[np.ndarray, ...] = (),
                  progress: bool = True, label: str = "scan", close_loops: bool = True) -> _Fused:
    """Track every frame against the model and fuse the accepted ones into `volume`.

    The first frame is placed at `guesses[0]` (identity when none) if the model is empty; with
    `tracking_model` (an earlier scan of the same place) the first frame is tracked against that model instead.
    With `close_loops`, frames that see the same place again are matched (loop.py); if any match holds, the
    poses are optimised and the volume is fused again from the frames at the optimised poses.
    """
    from tqdm import tqdm
    camera = sequence.intrinsics
    fused = _Fused([], [], None, [])
    keep_every = max(1, int(np.ceil(len(sequence) / MAX_VIEWS)))
    recent = RecentFrames()  # each frame's features and odometry pyramid, made once
    key_every = max(1, int(np.ceil(len(sequence) / MAX_KEYFRAMES)))
    keyframes: dict[int, Features] = {}
    edges: list[Edge] = []
    previous, previous_index = None, None
    bar = tqdm(range(len(sequence)), desc=label, unit="frame", disable=not progress, file=sys.stderr,
               leave=False)
    for index in bar:
        color, depth = read_frame(sequence, index)
        fused.depths.append(sample_depths(depth))
        if previous is None and volume.frames == 0 and tracking_model is None:
            pose, ok = (guesses[0] if guesses else np.eye(4)), True
        else:
            model = tracking_model if previous is None and volume.frames == 0 else volume
            result = track_frame(model, color, depth, camera, previous, params,
                                 guesses=guesses if previous is None else (), recent=recent)
            pose, ok = result.pose, result.accepted
            bar.set_postfix_str(f"fitness {result.fitness:.2f}" + ("" if ok else f", rejected ({result.reason})"))
            if ok:
                fused.fitness.append(result.fitness)
            else:
                fused.rejected.append((index, result.reason))
        fused.poses.append(pose)
        fused.accepted.append(ok)
        if not ok:
            continue  # a lost frame never touches the model
        volume.integrate(color, depth, camera, pose)
        if previous is not None:
            edges.append(Edge(previous_index, index, np.linalg.inv(pose) @ previous[2], _support(depth, camera),
                              False))
        if close_loops and index % key_every == 0:
            keyframes[index] = frame_features(color, depth, camera, recent)
        previous, previous_index = (color, depth, pose), index
        if index % keep_every == 0:
            fused.views.append((depth, pose, camera))
        if fused.first_view is None:
            fused.first_view = _world_points(depth, camera, pose)
    bar.close()
    fused.tracked = list(fused.poses)
    if close_loops and len(keyframes) > 3 and tracking_model is None:
        start = time.process_time()
        tracked = {i: fused.poses[i] for i in range(len(fused.poses)) if fused.accepted[i]}
        loops = loop_edges(tracked, keyframes, _dense_refiner(sequence, params, recent))
        if loops:
            _refuse(sequence, volume, fused, optimise(tracked, edges + loops), loops, progress, label)
        fused.closing_cpu = time.process_time() - start
    return fused


def _support(depth: np.ndarray, camera: Intrinsics) -> np.ndarray:
    """Information matrix of a dense alignment onto this frame: its depth points on a 40-column grid."""
    return information(_world_points(depth, camera, np.eye(4), stride=max(1, camera.width // 40)))


def _dense_refiner(sequence: RGBDSequence, params: TrackingParams, recent: RecentFrames):
    """refine(a, b, guess) for loop_edges: hybrid RGB-D odometry of frame a onto frame b from the guess."""
    frames: dict[int, tuple] = {}

    def load(index):
        if index not in frames:
            if len(frames) > 8:
                frames.pop(next(iter(frames)))
            frames[index] = read_frame(sequence, index)
        return frames[index]

    def refine(a: int, b: int, guess: np.ndarray):
        (color_a, depth_a), (color_b, depth_b) = load(a), load(b)
        transform = dense_motion(color_a, depth_a, color_b, depth_b, sequence.intrinsics, guess, params,
                                 recent=recent)
        return None if transform is None else (transform, _support(depth_b, sequence.intrinsics))
    return refine


def _refuse(sequence, volume, fused: _Fused, optimised: dict, loops: list, progress: bool, label: str) -> None:
    """Fuse the accepted frames again, into a cleared volume, at their optimised poses."""
    from tqdm import tqdm
    fused.moved = max(float(np.linalg.norm(optimised[i][:3, 3] - fused.poses[i][:3, 3])) for i in optimised)
    fused.loops = len(loops)
    keep_every = max(1, int(np.ceil(len(sequence) / MAX_VIEWS)))
    volume.clear()
    fused.views = []
    for index in tqdm(sorted(optimised), desc=f"{label} (loop closed)", unit="frame", disable=not progress,
                      file=sys.stderr, leave=False):
        color, depth = read_frame(sequence, index)
        fused.poses[index] = optimised[index]
        volume.integrate(color, depth, sequence.intrinsics, optimised[index])
        if index % keep_every == 0:
            fused.views.append((depth, optimised[index], sequence.intrinsics))


def _world_points(depth: np.ndarray, camera: Intrinsics, pose: np.ndarray, stride: int = 2) -> np.ndarray:
    """(N, 3) world points of a depth image (every `stride`-th pixel)."""
    v, u = np.mgrid[0:depth.shape[0]:stride, 0:depth.shape[1]:stride]
    z = depth[::stride, ::stride]
    ok = z > 0
    z, u, v = z[ok], u[ok], v[ok]
    points = np.stack([(u - camera.cx) * z / camera.fx, (v - camera.cy) * z / camera.fy, z], axis=1)
    return points @ pose[:3, :3].T + pose[:3, 3]


def scan(frames: str | Path, out_path: str | Path, *, segment: str | None = None, before: str | Path | None = None,
         voxel: float = 0.006, intrinsics: str | Path | Intrinsics | None = None, camera: str | None = None,
         depth_scale: float | None = None, depth_max: float = 3.0, target_faces: int | None = None,
         min_component: float = 0.02, tracking: TrackingParams = TrackingParams(), progress: bool = True,
         threads: int = 1, seed: int = 0) -> ScanResult:
    """Reconstruct the RGB-D sequence in `frames` and write the mesh to `out_path` (.ply, .obj or .glb).

    segment : None (whole scene), "plane" (remove the supporting plane, keep the object) or "change" (needs
              `before`, a scan of the same place without the object, or with it when the main one has none)
    voxel : TSDF voxel size in metres; depth_max : depth beyond this (metres) is ignored
    target_faces : decimate to about this many faces; min_component : floaters smaller than this fraction of
              the largest component are removed
    The mesh is in metres, +Y up: the first camera's frame turned upright, or with `segment="plane"` the plane
    is y = 0 and the object is centred above the origin. The plane is the dominant one in the first fused
    view (the paper's plane "from the current view"), which is where a scan of an object on a table starts.
    threads : OpenMP threads for Open3D's kernels (and OpenCV's pool). One is the default because on a shared
              CPU OpenMP's spin-waiting threads made each odometry call 10-50x slower in our measurements.
    """
    from threadpoolctl import threadpool_limits

    from .features import opencv
    cv2 = opencv()
    threads = max(1, int(threads))
    opencv_threads = cv2.getNumThreads()
    cv2.setNumThreads(threads)
    try:
        with threadpool_limits(limits=threads, user_api="openmp"):
            return _scan(frames, out_path, segment=segment, before=before, voxel=voxel, intrinsics=intrinsics,
                         camera=camera, depth_scale=depth_scale, depth_max=depth_max, target_faces=target_faces,
                         min_component=min_component, tracking=tracking, progress=progress, seed=seed)
    finally:
        cv2.setNumThreads(opencv_threads)


def _scan(frames, out_path, *, segment, before, voxel, intrinsics, camera, depth_scale, depth_max, target_faces,
          min_component, tracking, progress, seed) -> ScanResult:
    start = time.perf_counter()
    if segment not in SEGMENTS:
        raise BadScanError(f"unknown segmentation {segment!r}; choose plane or change")
    if segment == "change" and before is None:
        raise BadScanError("--segment change needs --before DIR (a scan of the same place with the object "
                           "moved)")
    if not voxel or not np.isfinite(voxel) or voxel <= 0 or voxel > 0.2:
        raise BadScanError(f"voxel size must be in (0, 0.2] metres, got {voxel}")
    if Path(out_path).suffix.lower() not in MESH_SUFFIXES:  # fail before minutes of fusion, not after
        raise ExportError(f"{out_path}: scan output must end in {', '.join(MESH_SUFFIXES)}")
    sequence = open_sequence(frames, intrinsics, depth_scale, camera)
    volume = TSDFVolume(voxel, depth_max=depth_max)
    used = rejected = 0
    before_volume, before_poses = None, []
    if before is not None:
        before_sequence = open_sequence(before, intrinsics if intrinsics is not None else sequence.intrinsics,
                                        depth_scale, camera)
        before_volume = TSDFVolume(voxel, depth_max=depth_max)
        pre = fuse_sequence(before_sequence, before_volume, tracking, progress=progress, label="before")
        before_poses = [p for p, ok in zip(pre.poses, pre.accepted) if ok]
        used, rejected = sum(pre.accepted), len(pre.accepted) - sum(pre.accepted)
        # The second sweep starts where either the first one ended or began; its first frame is tracked
        # against the first sweep's model, whose static background anchors both in one world.
        main = fuse_sequence(sequence, volume, tracking, tracking_model=before_volume,
                             guesses=(before_poses[-1], before_poses[0]), progress=progress)
        if not main.accepted[0]:
            raise BadScanError(f"{sequence.root}: its first frame could not be aligned with the --before scan "
                               f"{before_sequence.root}; start both sweeps from the same view")
    else:
        main = fuse_sequence(sequence, volume, tracking, progress=progress)
    used += sum(main.accepted)
    rejected += len(main.accepted) - sum(main.accepted)
    reading = depth_reading(main.depths, sequence.depth_scale, sequence.scale_source, depth_max)
    report = [reading.line()] + _tracking_report(main, len(sequence), "" if before is None else " (main sweep)")
    if before is not None:
        report = _tracking_report(pre, len(before_sequence), " (--before sweep)") + report

    vertices, faces, colors = volume.triangle_mesh()
    voxels = volume.voxels()
    report.append(f"fusion: {int(np.count_nonzero(voxels.weight > 0))} voxels fused at {voxel * 1000:g} mm "
                  f"({volume.grid.hashmap().size()} blocks); marching cubes: {len(vertices)} vertices, "
                  f"{len(faces)} faces")
    accepted_poses = np.array([p for p, ok in zip(main.poses, main.accepted) if ok])
    viewpoints = np.array([p[:3, 3] for p in accepted_poses] + [p[:3, 3] for p in before_poses])
    mesh = ScanMesh(vertices, faces, colors)
    transform = CAMERA_TO_Y_UP.copy()
    join = JOIN_VOXELS * voxel
    if segment == "change":
        change = changed_voxels(before_volume.voxels(), volume.voxels(), pre.views, main.views)
        if not change.object_in_after:
            vertices, faces, colors = before_volume.triangle_mesh()
            mesh = ScanMesh(vertices, faces, colors)
        mesh = cut_to_voxels(mesh, change.keys, voxel)
        report.append(f"change: {len(change.keys)} voxels changed, the object was "
                      f"{'added in' if change.object_in_after else 'taken away from'} the main sweep; "
                      f"{len(mesh.faces)} faces lie there")
    if len(mesh.faces) == 0:
        raise BadScanError(f"{sequence.root}: no surface was reconstructed; {reading.line()}; check the depth "
                           f"scale ({reading.alternatives()}) and --depth-max")
    if segment == "plane":
        first = next(p for p, ok in zip(main.poses, main.accepted) if ok)
        plane = dominant_plane(main.first_view, first[:3, 3], max(1.5 * voxel, 0.01), seed)
        before_cut = len(mesh.faces)
        mesh = cut_above_plane(mesh, plane, margin=max(2.0 * voxel, 0.01))
        report.append(f"plane: removed {before_cut - len(mesh.faces)} faces on or below the dominant plane of "
                      f"the first view; {len(mesh.faces)} left above it")
        choice = select_object(mesh, focus_point(accepted_poses), join)
        mesh = choice.mesh
        report.append(_choice_report(choice, join))
        transform = _upright_on_plane(mesh, plane)
    mesh, dropped = remove_floaters(mesh, min_component, join)
    if len(mesh.faces) == 0:
        raise BadScanError(f"{sequence.root}: nothing was left of the surface after segmentation; "
                           f"{reading.line()}; check the depth scale ({reading.alternatives()})")
    if dropped:
        report.append(f"floaters: dropped {len(dropped)} pieces (under {min_component:.0%} of the largest, or under "
                      f"{SPECK_JOINS * join * 100:.1f} cm across; faces: {_sizes(dropped)})")
    if target_faces:
        mesh = decimate(mesh, int(target_faces))
    mesh = orient_outward(mesh, viewpoints)
    mesh = mesh.transformed(transform)
    extent = np.ptp(mesh.vertices, axis=0) * 100
    report.append(f"kept: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces, "
                  f"{extent[0]:.0f} x {extent[1]:.0f} x {extent[2]:.0f} cm (x, y up, z)")
    warning = size_warning(reading, float(np.ptp(mesh.vertices, axis=0).max()), sequence.intrinsics.width,
                           sequence.intrinsics.fx)
    path = write_mesh(mesh, out_path)
    return ScanResult(path, int(used), int(rejected), len(mesh.vertices), len(mesh.faces),
                      time.perf_counter() - start, np.array(main.poses), np.array(main.accepted, bool), transform,
                      tuple(report), reading, () if warning is None else (warning,))


def _sizes(sizes: list, shown: int = 6) -> str:
    return ", ".join(map(str, sizes[:shown])) + (f" and {len(sizes) - shown} more" if len(sizes) > shown else "")


def _tracking_report(fused: _Fused, total: int, sweep: str) -> list[str]:
    lines = [f"frames{sweep}: {sum(fused.accepted)} of {total} used"]
    if fused.fitness:
        lines[0] += (f"; agreement with the model {min(fused.fitness):.2f}-{max(fused.fitness):.2f} "
                     f"(median {np.median(fused.fitness):.2f})")
    for index, reason in fused.rejected[:10]:
        lines.append(f"  rejected frame {index}: {reason}")
    if len(fused.rejected) > 10:
        lines.append(f"  ... and {len(fused.rejected) - 10} more rejected")
    if fused.loops:
        lines.append(f"loop closure: {fused.loops} matches between distant frames; poses adjusted by up to "
                     f"{fused.moved * 1000:.0f} mm and the frames fused again")
    return lines


def _choice_report(choice, join: float) -> str:
    return (f"components: {len(choice.sizes)} above the plane (pieces closer than {join * 100:.1f} cm counted "
            f"as one; faces: {_sizes(choice.sizes)}); kept the one with {choice.kept} faces: {choice.reason}")


def _upright_on_plane(mesh: ScanMesh, plane) -> np.ndarray:
    """(4, 4) rigid transform putting the plane at y = 0 with its normal +Y and the object above the origin."""
    flip = CAMERA_TO_Y_UP[:3, :3]
    rotation = minimal_rotations(flip @ plane.normal, np.array([0.0, 1.0, 0.0])) @ flip
    transform = np.eye(4)
    transform[:3, :3] = rotation
    # a point on the plane goes to y = 0; the object's footprint centre goes to x = z = 0
    moved = mesh.vertices @ rotation.T
    on_plane = -plane.offset * plane.normal
    transform[:3, 3] = [-moved[:, 0].mean(), -(rotation @ on_plane)[1], -moved[:, 2].mean()]
    return transform


def _frames_root(folder: Path) -> Path:
    """The shallowest folder under `folder` that holds a TUM or Redwood sequence."""
    candidates = [folder] + sorted((p for p in folder.rglob("*") if p.is_dir()), key=lambda p: len(p.parts))
    for path in candidates:
        if path.name == "__MACOSX":
            continue
        if (path / "depth.txt").is_file() or (path / "depth").is_dir():
            return path
    raise BadScanError("zip holds no RGB-D frames (expected rgb.txt + depth.txt, or color/ and depth/ folders)")


def scan_zip(zip_bytes_or_path: bytes | str | Path, out_path: str | Path, **options) -> ScanResult:
    """`scan` on frames uploaded as a zip (bytes or a path): the studio's "Scan" entry.

    The zip may hold the sequence at its top level or in one folder; an intrinsics JSON beside the frames is
    found as in `scan`. `options` are `scan`'s keywords (progress defaults to off).
    """
    options.setdefault("progress", False)
    source = io.BytesIO(zip_bytes_or_path) if isinstance(zip_bytes_or_path, (bytes, bytearray)) \
        else zip_bytes_or_path
    name = "uploaded zip" if isinstance(source, io.BytesIO) else str(source)
    with tempfile.TemporaryDirectory(prefix="kinetre-scan-") as tmp:
        try:
            with zipfile.ZipFile(source) as archive:
                archive.extractall(tmp)  # zipfile strips absolute paths and '..' from member names
        except (zipfile.BadZipFile, OSError) as exc:
            raise BadScanError(f"{name}: not a readable zip file ({exc})") from None
        return scan(_frames_root(Path(tmp)), out_path, **options)
