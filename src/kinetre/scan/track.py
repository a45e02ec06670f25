"""Camera tracking: frame-to-frame motion checked against the model, frame-to-model ICP as the fallback
(KinÊtre paper, "Acquisition").

For frame k with the previous accepted frame k-1 at pose T_{k-1} (camera-to-world):

1. motion: ORB features matched between the frames (features.py, any baseline) seed Open3D's hybrid (depth +
   photometric) RGB-D odometry from frame k to frame k-1, giving T_{k-1,k} and T_k = T_{k-1} T_{k-1,k}. On a
   40-frame 360-degree orbit (9 degrees between frames) dense odometry alone settled 1.5-8 degrees off and
   KinectFusion's frame-to-model ICP from that guess drifted by centimetres (Open3D 0.19's ray cast samples
   the TSDF at the nearest voxel, so the model it renders is terraced by +-3 mm at 6 mm voxels); features +
   odometry are 0.7 mm and 0.03 degrees per step, and loop closure (loop.py) removes the drift left.
   The odometry runs on an image pyramid no wider than `odometry_width` (`_pyramid`): 640x480 frames
   are halved once, as Open3D would, and each frame's half-size images are made once and serve as source and
   then as target. Iterating at 640x480 cost 2.2x the time for 0.67 instead of 0.75 mm per step (lamp orbit).
   Each level iterates until it settles (`odometry_tolerance`), at most `odometry_iterations` times;
2. the frame is scored against the model ray cast at T_k, at about 160x120 (`score_width`): `fitness` =
   fraction of the frame's valid pixels within `inlier_distance` of the model's surface, `rmse` = RMS depth
   residual of those inliers (metres);
3. only when there is no motion (no previous frame, or neither features nor odometry aligned) or it scores
   below `min_fitness` / above `max_rmse`, frame k is aligned to the model itself by multi-scale projective
   ICP (point-to-plane, and hybrid when that agrees with less than `retry_fitness`) from T_k, T_{k-1} and any
   `guesses` (the start of another sweep), keeping the best-scoring alignment. A frame that still scores
   below `min_fitness` or above `max_rmse` is lost and must not be fused.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..jit import njit
from .features import feature_motion
from .frames import Intrinsics
from .recent import RecentFrames, remembered
from .fuse import TSDFVolume


@dataclass(frozen=True)
class TrackingParams:
    """Thresholds of frame-to-model tracking (metres, fractions).

    min_fitness : fraction of the frame's valid pixels that must agree with the model (lower = lost)
    max_rmse : largest accepted RMS depth residual of the agreeing pixels
    inlier_distance : depth residual below which a pixel agrees with the model
    depth_outlier : correspondences farther apart are ignored by ICP
    model_method : "point-to-plane" or "hybrid" objective of the frame-to-model alignment
    retry_fitness : below this fitness the other objective is tried too and the better alignment kept
    icp_iterations, odometry_iterations : per pyramid level, coarsest first (Open3D's order), at most
    odometry_tolerance : a level of the odometry stops once an iteration changes its RMSE and fitness by less
        than this (relative). Up to 10 + 10 iterations so took as long as a fixed 6 + 4 on the Spot arc and
        erred 1.65 instead of 2.24 mm per step
    odometry_width : the finest level of frame-to-frame odometry is the frame halved until at most this wide
    score_width : the agreement with the model is measured on every 2^k-th pixel, about this many across
        (at least 160: Open3D 0.19's ray cast did not return at 80x60)
    """

    min_fitness: float = 0.3
    max_rmse: float = 0.02
    inlier_distance: float = 0.03
    depth_outlier: float = 0.07
    icp_iterations: tuple[int, ...] = (10, 5, 3)
    model_method: str = "point-to-plane"
    retry_fitness: float = 0.8
    odometry_iterations: tuple[int, ...] = (10, 10)
    odometry_tolerance: float = 1e-3
    odometry_width: int = 320
    score_width: int = 160


@dataclass(frozen=True)
class TrackResult:
    """Outcome of tracking one frame: pose (4, 4) float64 camera-to-world, scores, and why it was rejected."""

    pose: np.ndarray
    fitness: float
    rmse: float
    accepted: bool
    reason: str = ""


def _rgbd(o3d, color: np.ndarray, depth: np.ndarray):
    c = o3d.core
    if color.dtype == np.uint8:
        color = color.astype(np.float32) / 255.0
    return o3d.t.geometry.RGBDImage(o3d.t.geometry.Image(c.Tensor(np.ascontiguousarray(color, np.float32))),
                                    o3d.t.geometry.Image(c.Tensor(np.ascontiguousarray(depth, np.float32))))


def _odometry(o3d, source, target, camera: Intrinsics, depth_max: float, iterations, method, depth_outlier,
              init: np.ndarray | None = None, tolerance: float = 1e-6):
    """Source-to-target (4, 4) transform by Open3D's multi-scale RGB-D odometry, or None if it fails.

    iterations : per pyramid level, coarsest first (Open3D's order: (10, 5, 3) iterates 10 times at 1/4 size
    and 3 times at full size); a 0 skips that level. A level stops early once an iteration changes both the
    inlier RMSE and the fitness by less than `tolerance` (relative).
    """
    odo = o3d.t.pipelines.odometry
    criteria = [odo.OdometryConvergenceCriteria(n, tolerance, tolerance) for n in iterations]
    try:
        result = odo.rgbd_odometry_multi_scale(
            source, target, o3d.core.Tensor(camera.matrix), o3d.core.Tensor(np.eye(4) if init is None else init),
            1.0, depth_max, criteria, method, odo.OdometryLossParams(depth_outlier, depth_outlier * 0.7, 0.1))
    except RuntimeError:  # too few correspondences at some pyramid level
        return None
    transform = result.transformation.numpy().astype(np.float64)
    return transform if np.all(np.isfinite(transform)) else None


def agreement(depth: np.ndarray, model_depth: np.ndarray, camera: Intrinsics, model_from_frame: np.ndarray,
              inlier_distance: float, stride: int = 2) -> tuple[float, float]:
    """Score a frame against a model rendering: (fitness in [0, 1], rmse in metres).

    depth, model_depth : (H, W) float32 metres (0 = none); model_from_frame : (4, 4) maps frame camera
    coordinates into the rendering's camera. Every `stride`-th pixel is reprojected into the rendering and its
    depth compared with the model's there.
    """
    h, w = depth.shape
    v, u = np.mgrid[0:h:stride, 0:w:stride]
    z = depth[::stride, ::stride]
    valid = z > 0
    if not np.any(valid):
        return 0.0, float("inf")
    z, u, v = z[valid], u[valid], v[valid]
    points = np.stack([(u - camera.cx) * z / camera.fx, (v - camera.cy) * z / camera.fy, z], axis=1)
    points = points @ model_from_frame[:3, :3].T + model_from_frame[:3, 3]
    zm = points[:, 2]
    front = zm > 1e-6
    pu = np.full(len(zm), -1, np.int64)
    pv = np.full(len(zm), -1, np.int64)
    pu[front] = np.round(points[front, 0] * camera.fx / zm[front] + camera.cx).astype(np.int64)
    pv[front] = np.round(points[front, 1] * camera.fy / zm[front] + camera.cy).astype(np.int64)
    inside = front & (pu >= 0) & (pu < w) & (pv >= 0) & (pv < h)
    model = np.zeros(len(zm), np.float32)
    model[inside] = model_depth[pv[inside], pu[inside]]
    residual = np.abs(zm - model)
    inlier = inside & (model > 0) & (residual < inlier_distance)
    if not np.any(inlier):
        return 0.0, float("inf")
    return float(np.count_nonzero(inlier) / len(zm)), float(np.sqrt(np.mean(residual[inlier] ** 2)))


def _subsampled(camera: Intrinsics, factor: int) -> Intrinsics:
    """The camera of every `factor`-th pixel (pixel u there is pixel factor * u here)."""
    return Intrinsics(camera.width // factor, camera.height // factor, camera.fx / factor, camera.fy / factor,
                      camera.cx / factor, camera.cy / factor)


def _halvings(width: int, limit: int) -> int:
    count = 0
    while width > limit and width // 2 >= limit:
        width //= 2
        count += 1
    return count


_GAUSS5 = np.array([0.0625, 0.25, 0.375, 0.25, 0.0625], np.float32)


@njit(cache=True)
def _pyrdown_depth(depth: np.ndarray, max_difference: float) -> np.ndarray:  # pragma: no cover - numba
    """Depth halved as Open3D's pyramid does it (after ICPCUDA): the 5x5 Gaussian mean around every second
    pixel over the valid neighbours within `max_difference` of it; 0 where that pixel has no depth."""
    h, w = depth.shape[0] // 2, depth.shape[1] // 2
    out = np.zeros((h, w), np.float32)
    for y in range(h):
        for x in range(w):
            centre = depth[2 * y, 2 * x]
            if not centre > 0:
                continue
            total = 0.0
            weight = 0.0
            for dy in range(-2, 3):
                yy = 2 * y + dy
                if yy < 0 or yy >= depth.shape[0]:
                    continue
                for dx in range(-2, 3):
                    xx = 2 * x + dx
                    if xx < 0 or xx >= depth.shape[1]:
                        continue
                    d = depth[yy, xx]
                    if d > 0 and abs(d - centre) < max_difference:
                        wt = _GAUSS5[dy + 2] * _GAUSS5[dx + 2]
                        total += wt * d
                        weight += wt
            out[y, x] = total / weight
    return out


@dataclass(frozen=True)
class _Pyramid:
    """A frame as the odometry sees it: the Open3D RGB-D image `rgbd` of the halved frame, and its camera."""

    rgbd: object
    camera: Intrinsics


def _pyramid(o3d, color: np.ndarray, depth: np.ndarray, camera: Intrinsics, width: int,
             depth_outlier: float) -> _Pyramid:
    """The frame halved until at most `width` pixels wide, as Open3D's own pyramid would (colour by a Gaussian
    pyramid, depth by `_pyrdown_depth` with its threshold, twice the outlier distance)."""
    from .features import opencv
    cv2 = opencv()
    halvings = _halvings(camera.width, width)
    small_color = color.astype(np.float32) / np.float32(255.0) if color.dtype == np.uint8 else color
    small_depth = np.ascontiguousarray(depth, np.float32)
    for _ in range(halvings):
        small_color = cv2.pyrDown(small_color, dstsize=(small_color.shape[1] // 2, small_color.shape[0] // 2))
        small_depth = _pyrdown_depth(small_depth, np.float32(2.0 * depth_outlier))
    return _Pyramid(_rgbd(o3d, small_color, small_depth), _subsampled(camera, 2 ** halvings))


def frame_motion(color: np.ndarray, depth: np.ndarray, prev_color: np.ndarray, prev_depth: np.ndarray,
                 camera: Intrinsics, params: "TrackingParams" = None, depth_max: float = 3.0,
                 recent: RecentFrames | None = None) -> np.ndarray | None:
    """(4, 4) motion of the camera from the previous frame to this one (maps this frame's points into the
    previous camera), or None: ORB feature matches seed dense hybrid RGB-D odometry (module notes)."""
    motion = feature_motion(color, depth, prev_color, prev_depth, camera, recent=recent)
    init = motion.transform if motion is not None else None
    step = dense_motion(color, depth, prev_color, prev_depth, camera, init, params, depth_max, recent)
    return step if step is not None else init


def dense_motion(color: np.ndarray, depth: np.ndarray, other_color: np.ndarray, other_depth: np.ndarray,
                 camera: Intrinsics, init: np.ndarray | None, params: "TrackingParams" = None,
                 depth_max: float = 3.0, recent: RecentFrames | None = None) -> np.ndarray | None:
    """Hybrid (depth + photometric) RGB-D odometry mapping this frame's points into the other camera, from
    `init`, on the frames' pyramids (`_pyramid`, made once per frame of a scan that keeps `recent`;
    `params.odometry_iterations` per level, coarsest first)."""
    from .fuse import open3d
    o3d = open3d()
    params = params or TrackingParams()

    def pyramid(c, d):
        options = (params.odometry_width, params.depth_outlier)
        return remembered(recent, ("pyramid", c, d, camera, *options), lambda: _pyramid(o3d, c, d, camera, *options))
    source, target = pyramid(color, depth), pyramid(other_color, other_depth)
    return _odometry(o3d, source.rgbd, target.rgbd, source.camera, depth_max, params.odometry_iterations,
                     o3d.t.pipelines.odometry.Method.Hybrid, params.depth_outlier, init, params.odometry_tolerance)


def _score(volume: TSDFVolume, depth: np.ndarray, camera: Intrinsics, pose: np.ndarray,
           params: "TrackingParams") -> TrackResult:
    """Agreement of the frame placed at `pose` with the model rendered there, on every 2^k-th pixel so that the
    rendering is about `params.score_width` wide (a score: 19200 pixels at 160x120 decide it as well as 307200,
    and the ray cast costs 2.4x less)."""
    step = 2 ** _halvings(camera.width, max(160, params.score_width))
    small = _subsampled(camera, step)
    model_depth = volume.raycast_depth(small, pose)
    fitness, rmse = agreement(depth[: small.height * step: step, : small.width * step: step], model_depth, small,
                              np.eye(4), params.inlier_distance, stride=1)
    return TrackResult(pose, fitness, rmse, True)


def track_frame(volume: TSDFVolume, color: np.ndarray, depth: np.ndarray, camera: Intrinsics,
                previous: tuple[np.ndarray, np.ndarray, np.ndarray] | None,
                params: TrackingParams = TrackingParams(),
                guesses: tuple[np.ndarray, ...] = (), recent: RecentFrames | None = None) -> TrackResult:
    """Pose of one frame (colour (H, W, 3) uint8, depth (H, W) float32 m) against the fused model.

    previous : (colour, depth, pose) of the last accepted frame: its motion to this frame (`frame_motion`) gives
    the pose, which is kept when the frame agrees with the model there; otherwise (or without a previous frame)
    frame-to-model ICP starts from that pose, the previous one and `guesses` (e.g. the start of another
    sweep), and the best-scoring alignment wins. recent: the scan's `RecentFrames` (each frame's features and
    pyramid made once), if any.
    """
    from .fuse import open3d
    o3d = open3d()
    odo = o3d.t.pipelines.odometry
    methods = {"hybrid": odo.Method.Hybrid, "point-to-plane": odo.Method.PointToPlane}
    if params.model_method not in methods:
        from ..errors import BadScanError
        raise BadScanError(f"unknown tracking method {params.model_method!r}; choose {', '.join(methods)}")
    best = TrackResult(np.eye(4), 0.0, float("inf"), False, "no start pose aligned")
    starts = []
    if previous is not None:
        prev_color, prev_depth, prev_pose = previous
        step = frame_motion(color, depth, prev_color, prev_depth, camera, params, volume.depth_max, recent)
        if step is not None:
            best = _score(volume, depth, camera, prev_pose @ step, params)
            starts.append(best.pose)
        starts.append(prev_pose)
    starts.extend(guesses)
    if not starts:
        starts.append(np.eye(4))
    if best.fitness < params.min_fitness or best.rmse > params.max_rmse:
        # no frame-to-frame motion, or it disagrees with the model: align to the model itself (KinectFusion).
        # Not otherwise: the agreement favours poses that see more of the model, and after a 12-degree step
        # with the model made of one frame, ICP from the previous pose "agreed" better 14 degrees off.
        best = _model_icp(o3d, volume, color, depth, camera, starts, params, methods, best)
    if best.fitness < params.min_fitness:
        return TrackResult(best.pose, best.fitness, best.rmse, False,
                           f"lost tracking: fitness {best.fitness:.2f} < {params.min_fitness}")
    if best.rmse > params.max_rmse:
        return TrackResult(best.pose, best.fitness, best.rmse, False,
                           f"lost tracking: rmse {best.rmse * 1000:.1f} mm > {params.max_rmse * 1000:.1f} mm")
    return best


def _model_icp(o3d, volume, color, depth, camera, starts, params, methods, best: TrackResult) -> TrackResult:
    """Frame-to-model projective ICP from each start; the alignment agreeing best with the model."""
    odo = o3d.t.pipelines.odometry
    frame = _rgbd(o3d, color, depth)
    primary = methods[params.model_method]
    secondary = odo.Method.Hybrid if primary == odo.Method.PointToPlane else odo.Method.PointToPlane
    renders = {}
    for method in (primary, secondary):
        if method is secondary and best.fitness >= params.retry_fitness:
            break
        for index, start in enumerate(starts):
            if index not in renders:
                renders[index] = volume.raycast(camera, start)
            model_color, model_depth = renders[index]
            if not np.any(model_depth > 0):
                continue
            refine = _odometry(o3d, frame, _rgbd(o3d, model_color, model_depth), camera, volume.depth_max,
                               params.icp_iterations, method, params.depth_outlier)
            if refine is None:
                continue
            fitness, rmse = agreement(depth, model_depth, camera, refine, params.inlier_distance)
            if fitness > best.fitness:
                best = TrackResult(start @ refine, fitness, rmse, True)
            if best.fitness >= params.retry_fitness:  # good enough: skip the other starts
                break
    return best
