"""Synthetic RGB-D ground truth: known meshes on a floor, rendered by Open3D's RaycastingScene with Kinect noise.

World frame: +Y up, the floor's top at y = 0, the object standing on it around the origin. Camera poses are
camera-to-world with OpenCV axes (x right, y down, z forward).

Scenes: Spot the cow on a slab (`spot_on_plane`), and composite objects of thin and thick parts (`OBJECTS`:
a desk lamp, a chair, a stick figure) on a textured 2 x 2 m floor beside a 10 cm cube (`object_scene`), for
full 360-degree orbits (`full_orbit`). As a script it writes such an orbit as a Redwood folder:

    python tests/scan/scan_synthetic.py lamp /tmp/lamp --frames 40 --size 640x480
"""
from __future__ import annotations

import argparse
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
    """object_vertices/faces : the true object surface; others : everything else in the scene.

    floor : index in the others of the floor (or None); distractor : index of the object we must not keep
    tile : edge (metres) of the random grey tiles printed on everything but the object (0 = smooth only)
    """

    object_vertices: np.ndarray
    object_faces: np.ndarray
    other_vertices: list
    other_faces: list
    floor: int | None = 0
    distractor: int | None = None
    tile: float = 0.0


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


def _cylinder(radius: float, start, end, sections: int = 24) -> trimesh.Trimesh:
    return trimesh.creation.cylinder(radius=radius, segment=np.array([start, end], float), sections=sections)


def _sphere(radius: float, centre) -> trimesh.Trimesh:
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    sphere.apply_translation(centre)
    return sphere


def _box(size, centre) -> trimesh.Trimesh:
    box = trimesh.creation.box(size)
    box.apply_translation(centre)
    return box


def lamp() -> list[trimesh.Trimesh]:
    """A desk lamp: 33 x 56 x 20 cm. Base disc r 10 cm, arms r 1.2 and 1 cm, two joint spheres,
    and a cone shade hanging from the upper joint (the arm reaches it from above, where the cameras see it)."""
    shade = trimesh.creation.cone(radius=0.075, height=0.12, sections=48)  # apex at +z
    axis = np.array([0.6, -1.0, 0.0]) / np.linalg.norm([0.6, -1.0, 0.0])  # base to apex goes against this
    shade.apply_translation((0.0, 0.0, -0.12))  # apex at the origin
    shade.apply_transform(trimesh.geometry.align_vectors([0.0, 0.0, -1.0], axis))
    shade.apply_translation((0.11, 0.54, 0.0))
    return [_cylinder(0.10, (0, 0, 0), (0, 0.025, 0), 64), _cylinder(0.012, (0.0, 0.02, 0.0), (-0.03, 0.30, 0.0)),
            _sphere(0.018, (-0.03, 0.30, 0.0)), _cylinder(0.010, (-0.03, 0.30, 0.0), (0.11, 0.54, 0.0)),
            _sphere(0.02, (0.11, 0.54, 0.0)), shade]


def chair() -> list[trimesh.Trimesh]:
    """A 40 x 80 x 40 cm chair: a 3 cm seat and a backrest rail on thin legs and posts (r 1 and 1.2 cm)."""
    parts = [_box((0.40, 0.03, 0.40), (0.0, 0.445, 0.0)), _box((0.40, 0.08, 0.03), (0.0, 0.76, -0.185))]
    for x in (-0.18, 0.18):
        for z in (-0.18, 0.18):
            parts.append(_cylinder(0.012, (x, 0.0, z), (x, 0.43, z)))
        parts.append(_cylinder(0.010, (x, 0.46, -0.185), (x, 0.72, -0.185)))
    return parts


def figure() -> list[trimesh.Trimesh]:
    """A 60 cm stick figure, arms out: box torso, sphere head, thin limbs (r 1-1.5 cm) on two feet."""
    parts = [_box((0.14, 0.20, 0.08), (0.0, 0.38, 0.0)), _sphere(0.06, (0.0, 0.54, 0.0)),
             _cylinder(0.010, (0.06, 0.45, 0.0), (0.30, 0.52, 0.0)), _cylinder(0.010, (-0.06, 0.45, 0.0),
                                                                              (-0.28, 0.36, 0.06))]
    for x in (-0.045, 0.045):
        parts += [_cylinder(0.015, (x, 0.02, 0.0), (x, 0.29, 0.0)), _box((0.06, 0.025, 0.11), (x, 0.0125, 0.02))]
    return parts


OBJECTS = {"lamp": lamp, "chair": chair, "figure": figure}


def object_scene(parts: list[trimesh.Trimesh], floor_size: float = 2.0, distractor=(-0.5, 0.0, 0.1),
                 cube: float = 0.10) -> Scene:
    """The parts (overlapping primitives, metres, standing on y = 0) on a floor slab, with a cube beside them.

    The cube sits `distractor` (its footprint centre) from the object: the scan must not keep it.
    """
    merged = trimesh.util.concatenate(parts)
    floor = _box((floor_size, 0.04, floor_size), (0.0, -0.02, 0.0))
    box = _box((cube, cube, cube), (distractor[0], cube / 2, distractor[2]))
    return Scene(np.asarray(merged.vertices, float), np.asarray(merged.faces), [np.asarray(floor.vertices),
                 np.asarray(box.vertices)], [np.asarray(floor.faces), np.asarray(box.faces)], 0, 1, 0.04)


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


def full_orbit(frames: int, radius: float = 1.1, height: float = 0.65, target=(0.05, 0.25, 0.0),
               wobble: float = 0.05) -> np.ndarray:
    """(frames, 4, 4) poses on a closed 360-degree loop (no repeated end frame) looking at `target`.

    A hand-held sweep is not a perfect circle: the radius and height wander by +-`wobble` metres.
    """
    angles = np.linspace(0.0, 2.0 * np.pi, frames, endpoint=False)
    r = radius + wobble * np.sin(3.0 * angles)
    h = height + wobble * np.cos(2.0 * angles)
    return np.array([look_at((x * np.sin(a), y, x * np.cos(a)), target) for a, x, y in zip(angles, r, h)])


def _texture(points: np.ndarray, is_object: np.ndarray, tile: float = 0.0) -> np.ndarray:
    """Procedural colour (N, 3) in [0, 1] so photometric odometry has something to lock on to."""
    s = np.sin(23.0 * points[:, 0]) * np.sin(19.0 * points[:, 2]) + 0.5 * np.sin(31.0 * points[:, 1])
    base = np.where(is_object[:, None], [0.85, 0.55, 0.35], [0.35, 0.55, 0.8])
    shade = 0.65 + 0.3 * s
    if tile > 0:  # a random grey per tile (a hash of the tile's indices): sharp edges everywhere on the floor
        cell = np.floor(points / tile)
        noise = np.modf(np.abs(np.sin(cell @ [12.9898, 4.1414, 78.233]) * 43758.5453))[0]
        shade = np.where(is_object, shade, 0.35 + 0.6 * noise + 0.1 * s)
    return np.clip(base * shade[:, None], 0.0, 1.0)


def render(scene: Scene, poses: np.ndarray, k: np.ndarray, width: int, height: int, noise: bool = True,
           seed: int = 0) -> tuple[list, list, list]:
    """Per pose: colour (H, W, 3) uint8, noisy depth (H, W) float32 m, exact object mask (H, W) bool.

    Noise: axial Gaussian sigma(z) = 1.2 mm + 1.9 mm (z - 0.4 m)^2 (Nguyen et al. 2012, Kinect v1), then
    millimetre quantisation as in 16-bit depth PNGs.
    """
    colors, depths, _, masks = render_with_exact(scene, poses, k, width, height, noise, seed)
    return colors, depths, masks


def render_with_exact(scene: Scene, poses: np.ndarray, k: np.ndarray, width: int, height: int, noise: bool = True,
                      seed: int = 0) -> tuple[list, list, list, list]:
    """`render`'s colour, depth and mask, and the depth without noise (quantised alike), from one ray cast."""
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
    colors, depths, exact, masks = [], [], [], []
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
        exact.append((np.round(depth * 1000.0) / 1000.0).astype(np.float32))
        if noise:
            sigma = 0.0012 + 0.0019 * (depth - 0.4) ** 2
            depth = np.where(ok, depth + rng.normal(size=depth.shape) * sigma, 0.0)
        depth = np.round(depth * 1000.0) / 1000.0
        normals = hit["primitive_normals"].numpy()
        shade = np.abs(np.einsum("hwc,hwc->hw", normals, r[..., 3:] / np.linalg.norm(r[..., 3:], axis=-1,
                                                                                      keepdims=True)))
        color = _texture(points.reshape(-1, 3), mask.reshape(-1), scene.tile).reshape(height, width, 3)
        color = np.where(ok[..., None], color * (0.4 + 0.6 * shade[..., None]), 0.0)
        colors.append(np.round(color * 255).astype(np.uint8))
        depths.append(depth.astype(np.float32))
        masks.append(mask)
    return colors, depths, exact, masks


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


def seen_points(poses: np.ndarray, depths, masks, k: np.ndarray, stride: int = 1) -> np.ndarray:
    """(N, 3) world points of the masked pixels of (exact) depth images: the part of a surface the camera saw."""
    seen = []
    for pose, depth, mask in zip(poses, depths, masks):
        v, u = np.nonzero(mask)
        z = depth[v, u]
        points = np.stack([(u - k[0, 2]) * z / k[0, 0], (v - k[1, 2]) * z / k[1, 1], z], 1)
        seen.append(points @ pose[:3, :3].T + pose[:3, 3])
    return np.concatenate(seen)[::stride]


@dataclass(frozen=True)
class Orbit:
    """A rendered sequence with its ground truth: noisy colour + depth, exact depth, object masks, poses."""

    scene: Scene
    poses: np.ndarray
    k: np.ndarray
    width: int
    height: int
    colors: list
    depths: list
    exact: list
    masks: list

    def write(self, folder: Path) -> Path:
        """The noisy frames as a Redwood folder with intrinsics.json."""
        return write_redwood(Path(folder), self.colors, self.depths, self.k, self.width, self.height)


def render_orbit(name: str, frames: int = 40, width: int = 640, height: int = 480, seed: int = 0,
                 **orbit_options) -> Orbit:
    """OBJECTS[name] on the textured floor beside the cube, seen from a full orbit (`full_orbit` options)."""
    scene = object_scene(OBJECTS[name]())
    poses = full_orbit(frames, **orbit_options)
    k = camera_matrix(width, height)
    colors, depths, exact, masks = render_with_exact(scene, poses, k, width, height, noise=True, seed=seed)
    return Orbit(scene, poses, k, width, height, colors, depths, exact, masks)


def main() -> None:
    parser = argparse.ArgumentParser(description="Write a synthetic 360-degree RGB-D orbit as a Redwood folder "
                                                 "(color/, depth/ in mm, intrinsics.json, poses.npy ground truth)")
    parser.add_argument("object", choices=sorted(OBJECTS))
    parser.add_argument("folder", type=Path)
    parser.add_argument("--frames", type=int, default=40)
    parser.add_argument("--size", default="640x480", help="WIDTHxHEIGHT (default 640x480)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    width, height = (int(n) for n in args.size.lower().split("x"))
    orbit = render_orbit(args.object, args.frames, width, height, args.seed)
    orbit.write(args.folder)
    np.save(args.folder / "poses.npy", orbit.poses)
    print(f"{args.folder}: {args.frames} frames of the {args.object}, {width}x{height}")


if __name__ == "__main__":
    main()
