"""Synthetic RGB-D ground truth: a known mesh on a plane, rendered by Open3D's RaycastingScene with Kinect noise.

World frame: +Y up, the ground plane's top at y = 0, the object standing on it around the origin. Camera poses are
camera-to-world with OpenCV axes (x right, y down, z forward).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import open3d as o3d
import trimesh
from PIL import Image

DATA = Path(__file__).resolve().parents[2] / ".." / "shared" / "data"
SPOT = DATA / "meshes" / "spot.obj"
REDWOOD = DATA / "rgbd" / "redwood_livingroom"


@dataclass(frozen=True)
class Scene:
    """object_vertices/faces : the true object surface; others : everything else in the scene."""

    object_vertices: np.ndarray
    object_faces: np.ndarray
    other_vertices: list
    other_faces: list


def _clutter() -> tuple[list, list]:
    """Two static boxes behind the object: a bare floor gives ICP nothing to hold on to across it."""
    boxes = [trimesh.creation.box((0.25, 0.3, 0.25)), trimesh.creation.box((0.2, 0.18, 0.3))]
    boxes[0].apply_translation((-0.4, 0.15, -0.35))
    boxes[1].apply_translation((0.4, 0.09, -0.3))
    return [np.asarray(b.vertices) for b in boxes], [np.asarray(b.faces) for b in boxes]


def spot_on_plane(length: float = 0.4, plane_size: float = 1.2, offset=(0.0, 0.0, 0.0),
                  clutter: bool = False) -> Scene:
    """Spot the cow scaled to `length` metres long, standing on a square slab whose top is y = 0."""
    mesh = trimesh.load(SPOT, force="mesh", process=True)
    vertices = np.asarray(mesh.vertices, float)
    vertices = (vertices - vertices.min(0)) * (length / np.ptp(vertices, axis=0).max())
    vertices -= [np.ptp(vertices[:, 0]) / 2, 0.0, np.ptp(vertices[:, 2]) / 2]
    vertices += offset
    slab = trimesh.creation.box((plane_size, 0.04, plane_size))
    slab.apply_translation((0.0, -0.02, 0.0))
    scene = empty_plane(plane_size, clutter)
    return Scene(vertices, np.asarray(mesh.faces), scene.other_vertices, scene.other_faces)


def empty_plane(plane_size: float = 1.2, clutter: bool = False) -> Scene:
    """The slab alone (with `clutter`, two boxes on it): the scene once the object is taken away."""
    slab = trimesh.creation.box((plane_size, 0.04, plane_size))
    slab.apply_translation((0.0, -0.02, 0.0))
    vertices, faces = _clutter() if clutter else ([], [])
    return Scene(np.zeros((0, 3)), np.zeros((0, 3), int), [np.asarray(slab.vertices)] + vertices,
                 [np.asarray(slab.faces)] + faces)


def look_at(eye, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """(4, 4) camera-to-world pose of an OpenCV camera at `eye` looking at `target`."""
    eye, target, up = (np.asarray(a, float) for a in (eye, target, up))
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)  # y down: x = forward x up
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, y, z], axis=1)
    pose[:3, 3] = eye
    return pose


def orbit(frames: int, radius: float = 0.9, height: float = 0.55, arc_degrees: float = 90.0,
          target=(0.0, 0.12, 0.0)) -> np.ndarray:
    """(frames, 4, 4) poses on a horizontal arc around the object, all looking at `target`."""
    angles = np.radians(np.linspace(0.0, arc_degrees, frames)) + np.radians(20.0)
    return np.array([look_at((radius * np.sin(a), height, radius * np.cos(a)), target) for a in angles])


def _texture(points: np.ndarray, is_object: np.ndarray) -> np.ndarray:
    """Procedural colour (N, 3) in [0, 1] so photometric odometry has something to lock on to."""
    s = np.sin(23.0 * points[:, 0]) * np.sin(19.0 * points[:, 2]) + 0.5 * np.sin(31.0 * points[:, 1])
    base = np.where(is_object[:, None], [0.85, 0.55, 0.35], [0.35, 0.55, 0.8])
    return np.clip(base * (0.65 + 0.3 * s[:, None]), 0.0, 1.0)


def render(scene: Scene, poses: np.ndarray, k: np.ndarray, width: int, height: int, noise: bool = True,
           seed: int = 0) -> tuple[list, list, list]:
    """Per pose: colour (H, W, 3) uint8, noisy depth (H, W) float32 m, exact object mask (H, W) bool.

    Noise: axial Gaussian sigma(z) = 1.2 mm + 1.9 mm (z - 0.4 m)^2 (Nguyen et al. 2012, Kinect v1), then
    millimetre quantisation as in 16-bit depth PNGs.
    """
    rs = o3d.t.geometry.RaycastingScene()
    object_id = -1
    if len(scene.object_faces):
        object_id = rs.add_triangles(o3d.core.Tensor(scene.object_vertices.astype(np.float32)),
                                     o3d.core.Tensor(scene.object_faces.astype(np.uint32)))
    for v, f in zip(scene.other_vertices, scene.other_faces):
        rs.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
    rng = np.random.default_rng(seed)
    # RaycastingScene shoots through pixel corners + 0.5; shift the centre so pixel u sees (u - cx) / fx.
    k_rays = k.copy()
    k_rays[:2, 2] += 0.5
    colors, depths, masks = [], [], []
    for pose in poses:
        rays = rs.create_rays_pinhole(o3d.core.Tensor(k_rays), o3d.core.Tensor(np.linalg.inv(pose)), width, height)
        hit = rs.cast_rays(rays)
        t = hit["t_hit"].numpy()
        r = rays.numpy()
        ok = np.isfinite(t)
        points = r[..., :3] + r[..., 3:] * np.where(ok, t, 0)[..., None]
        camera_points = (points - pose[:3, 3]) @ pose[:3, :3]
        depth = np.where(ok, camera_points[..., 2], 0.0)
        mask = ok & (hit["geometry_ids"].numpy() == object_id)
        if noise:
            sigma = 0.0012 + 0.0019 * (depth - 0.4) ** 2
            depth = np.where(ok, depth + rng.normal(size=depth.shape) * sigma, 0.0)
        depth = np.round(depth * 1000.0) / 1000.0
        normals = hit["primitive_normals"].numpy()
        shade = np.abs(np.einsum("hwc,hwc->hw", normals, r[..., 3:] / np.linalg.norm(r[..., 3:], axis=-1,
                                                                                      keepdims=True)))
        color = _texture(points.reshape(-1, 3), mask.reshape(-1)).reshape(height, width, 3)
        color = np.where(ok[..., None], color * (0.4 + 0.6 * shade[..., None]), 0.0)
        colors.append(np.round(color * 255).astype(np.uint8))
        depths.append(depth.astype(np.float32))
        masks.append(mask)
    return colors, depths, masks


def write_redwood(folder: Path, colors, depths, k: np.ndarray, width: int, height: int,
                  intrinsics_name: str | None = "intrinsics.json") -> Path:
    """Write frames as color/NNNNN.png + depth/NNNNN.png (16-bit mm) and an Open3D intrinsics JSON."""
    (folder / "color").mkdir(parents=True, exist_ok=True)
    (folder / "depth").mkdir(parents=True, exist_ok=True)
    for i, (c, d) in enumerate(zip(colors, depths)):
        Image.fromarray(c).save(folder / "color" / f"{i:05d}.png")
        Image.fromarray(np.round(d * 1000).astype(np.uint16)).save(folder / "depth" / f"{i:05d}.png")
    if intrinsics_name:
        (folder / intrinsics_name).write_text(json.dumps(
            {"width": width, "height": height, "intrinsic_matrix": list(k.T.reshape(-1))}))
    return folder


def camera_matrix(width: int, height: int) -> np.ndarray:
    """Kinect v1 (fx = fy = 525 at 640x480) scaled to width x height."""
    s = width / 640.0
    return np.array([[525.0 * s, 0.0, (319.5 + 0.5) * s - 0.5], [0.0, 525.0 * s, (239.5 + 0.5) * s - 0.5],
                     [0.0, 0.0, 1.0]])


def surface_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N,) unsigned distance of (N, 3) points to a triangle mesh."""
    rs = o3d.t.geometry.RaycastingScene()
    rs.add_triangles(o3d.core.Tensor(vertices.astype(np.float32)), o3d.core.Tensor(faces.astype(np.uint32)))
    return rs.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()


def to_world(vertices: np.ndarray, transform: np.ndarray, first_pose: np.ndarray) -> np.ndarray:
    """Output-mesh vertices (N, 3) back to the synthetic world: undo the output transform, then camera 0."""
    inverse = np.linalg.inv(transform)
    camera = vertices @ inverse[:3, :3].T + inverse[:3, 3]
    return camera @ first_pose[:3, :3].T + first_pose[:3, 3]
