"""Wide-baseline motion guess between two RGB-D frames: ORB features, 3D matches, RANSAC rigid fit *(ours)*.

Dense RGB-D odometry and projective ICP only converge within a few degrees of the answer: on a 40-frame
360-degree orbit (9 degrees and 19 cm between frames) both settled 1.5-8 degrees off and the scan drifted by
metres. Features matched by descriptor do not care how far the camera moved: ORB keypoints (OpenCV) of both
colour images are lifted to 3D with their depth, matched (mutual nearest neighbours in Hamming distance), and
the rigid motion with the most matches within `inlier_distance` is found by RANSAC over 3-point samples
(Kabsch's least-squares rotation), then refitted on all its inliers. The result only seeds ICP, which has
the last word (track.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .frames import Intrinsics
from .recent import RecentFrames, remembered

ORB_FEATURES = 1000
# consecutive frames are matched on their strongest keypoints only: the seed needs a dozen good matches, and
# matching is quadratic (1000 x 1000 cost 17 ms, 500 x 500 about 5); loop closure matches all of them
TRACKING_FEATURES = 500


@dataclass(frozen=True)
class FeatureMotion:
    """transform : (4, 4) maps points of camera `a` into camera `b`; inliers : matches that agree with it.

    target_points : (inliers, 3) the agreeing points in camera `b` (they weigh the motion in a pose graph)
    """

    transform: np.ndarray
    inliers: int
    matches: int
    target_points: np.ndarray


def opencv():
    """The cv2 module, or a clear error when the scan extra is not installed."""
    try:
        import cv2
    except ImportError:
        from ..errors import BadScanError
        raise BadScanError("scanning needs OpenCV: pip install 'kinetre[scan]'") from None
    return cv2


@dataclass(frozen=True)
class Features:
    """ORB descriptors (M, 32) uint8 and camera-space points (M, 3) metres of the keypoints that have a depth,
    strongest (Harris response) first."""

    descriptors: np.ndarray
    points: np.ndarray

    def strongest(self, count: int) -> "Features":
        return Features(self.descriptors[:count], self.points[:count])


def frame_features(color: np.ndarray, depth: np.ndarray, camera: Intrinsics,
                   recent: RecentFrames | None = None) -> Features:
    """ORB keypoints of the colour image lifted to 3D with the depth (made once per frame of a scan that keeps
    `recent`)."""
    return remembered(recent, ("orb", color, depth, camera), lambda: _describe(color, depth, camera))


def _describe(color: np.ndarray, depth: np.ndarray, camera: Intrinsics) -> Features:
    cv2 = opencv()
    gray = cv2.cvtColor(np.ascontiguousarray(color), cv2.COLOR_RGB2GRAY)
    keypoints, descriptors = cv2.ORB_create(nfeatures=ORB_FEATURES).detectAndCompute(gray, None)
    if descriptors is None or len(keypoints) == 0:
        features = Features(np.zeros((0, 32), np.uint8), np.zeros((0, 3)))
    else:
        uv = np.array([k.pt for k in keypoints])
        u = np.clip(np.round(uv[:, 0]).astype(np.int64), 0, depth.shape[1] - 1)
        v = np.clip(np.round(uv[:, 1]).astype(np.int64), 0, depth.shape[0] - 1)
        z = depth[v, u].astype(np.float64)
        points = np.stack([(uv[:, 0] - camera.cx) * z / camera.fx, (uv[:, 1] - camera.cy) * z / camera.fy, z], 1)
        order = np.argsort([-k.response for k in keypoints], kind="stable")
        order = order[z[order] > 0]
        features = Features(descriptors[order], points[order])
    return features


def kabsch(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(..., 4, 4) rigid transforms minimising sum |R a_i + t - b_i|^2 for (..., N, 3) point sets (Kabsch)."""
    ca, cb = a.mean(axis=-2, keepdims=True), b.mean(axis=-2, keepdims=True)
    h = np.swapaxes(a - ca, -1, -2) @ (b - cb)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.swapaxes(vt, -1, -2) @ np.swapaxes(u, -1, -2)))
    fix = np.ones(h.shape[:-1])
    fix[..., 2] = d
    rotation = np.swapaxes(vt, -1, -2) @ (fix[..., :, None] * np.swapaxes(u, -1, -2))
    transform = np.zeros(h.shape[:-2] + (4, 4))
    transform[..., :3, :3] = rotation
    transform[..., :3, 3] = cb[..., 0, :] - (rotation @ np.swapaxes(ca, -1, -2))[..., 0]
    transform[..., 3, 3] = 1.0
    return transform


def feature_motion(color_a: np.ndarray, depth_a: np.ndarray, color_b: np.ndarray, depth_b: np.ndarray,
                   camera: Intrinsics, strongest: int | None = TRACKING_FEATURES, recent: RecentFrames | None = None,
                   **options) -> FeatureMotion | None:
    """Rigid motion from frame a to frame b (colour (H, W, 3) uint8, depth (H, W) float32 m), or None.

    Only the `strongest` keypoints of each frame are matched (all with None). None when fewer than
    `min_inliers` matches agree (too little texture, or no overlap). recent: the scan's `RecentFrames`, if
    any. options: `match`'s.
    """
    a, b = frame_features(color_a, depth_a, camera, recent), frame_features(color_b, depth_b, camera, recent)
    if strongest is not None:
        a, b = a.strongest(strongest), b.strongest(strongest)
    return match(a, b, **options)


def match(a: Features, b: Features, inlier_distance: float = 0.02, hypotheses: int = 256, min_inliers: int = 12,
          seed: int = 0) -> FeatureMotion | None:
    """Rigid motion taking the points of `a` onto those of `b` by RANSAC over mutual descriptor matches."""
    if len(a.descriptors) < min_inliers or len(b.descriptors) < min_inliers:
        return None
    cv2 = opencv()
    pairs = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True).match(a.descriptors, b.descriptors)
    if len(pairs) < min_inliers:
        return None
    pa = a.points[[m.queryIdx for m in pairs]]
    pb = b.points[[m.trainIdx for m in pairs]]
    samples = np.random.default_rng(seed).integers(0, len(pa), (hypotheses, 3))
    candidates = kabsch(pa[samples], pb[samples])  # (K, 4, 4), degenerate samples just score badly
    moved = candidates[:, :3, :3] @ pa.T + candidates[:, :3, 3:]  # (K, 3, N)
    inlier = np.sum((moved - pb.T[None]) ** 2, axis=1) < inlier_distance ** 2
    keep = inlier[int(np.argmax(inlier.sum(axis=1)))]
    for _ in range(2):  # refit on the consensus, then re-collect it
        if np.count_nonzero(keep) < min_inliers:
            return None
        transform = kabsch(pa[keep], pb[keep])
        keep = np.linalg.norm(pa @ transform[:3, :3].T + transform[:3, 3] - pb, axis=1) < inlier_distance
    if np.count_nonzero(keep) < min_inliers:
        return None
    return FeatureMotion(transform, int(np.count_nonzero(keep)), len(pairs), pb[keep])
