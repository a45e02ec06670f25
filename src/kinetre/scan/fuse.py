"""TSDF fusion (KinÊtre paper, "Acquisition"): each depth frame updates a truncated signed distance by a
weighted running average.

    D(x) <- (W(x) D(x) + d(x)) / (W(x) + 1),   W(x) <- W(x) + 1

where d(x) in [-1, 1] is the signed distance of voxel x to the surface seen along its camera ray, divided by the
truncation distance (`trunc_voxels` voxels). Storage is Open3D's sparse `t.geometry.VoxelBlockGrid` (hashed 8^3
blocks), which integrates, ray casts and runs marching cubes on the CPU. (Open3D 0.20's legacy
ScalableTSDFVolume extracts nothing; the tensor grid works in 0.19 and 0.20.)

Poses are camera-to-world (4, 4) float64; cameras look down +z with y down (OpenCV / Open3D convention).

Open3D 0.19's tensor TSDF has two half-unit offsets, measured on exact synthetic renderings and undone here:
integration looks up the depth pixel of a voxel by truncating its projection (not rounding), and the ray
caster reports surfaces half a voxel (along each axis) short of where they were fused. Uncorrected, marching
cubes lay 3.4 mm from the true surface instead of 0.4 mm (320x240, 1 cm voxels) and a ray cast rendered a
single fused frame 1.6 cm behind it. So frames are integrated with the principal point moved by +1/2 pixel,
and ray casts start from the camera moved by +1/2 voxel on each axis.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .frames import Intrinsics

# Truncation in voxels *(ours)*. Thin parts need it short: with 6 voxels (3.6 cm at 6 mm) the 2 cm arm of our
# synthetic desk lamp vanished over 8 cm of its length even with exact depth and true poses (the negative
# band a view writes behind a surface reaches past the arm's far side, into space other views see as free);
# with 4 voxels it was still eroded, with 3 it is whole (its surface 10-12 mm from the axis, radius 10 mm).
TRUNC_VOXELS = 3.0

# Open3D's ray cast first bounds each ray by a range map with one entry per RANGE_TILE x RANGE_TILE pixels,
# sized width // RANGE_TILE by height // RANGE_TILE: the pixels past the last whole tile read beyond that map,
# memory nobody wrote. Garbage there can make a ray march forever (a step too small to move t towards an
# enormous bound: the ray cast of a 40x30 frame hung in about one run in three) or lose those rows (Open3D
# issues 4658 and 6821). So rays are cast on the image padded to whole tiles, and the pad is cut off.
RANGE_TILE = 8
# Open3D 0.19 keeps the rectangles that build that range map (one or more per block in view) in a buffer of
# the grid, first sized by a guess that is 0 for a small image and large voxels. A ray cast needing more
# rectangles than it holds drops the blocks past its end (their tiles render empty: a fresh grid's first
# ray cast of a 40x30 frame rendered nothing), may read rectangles nobody wrote (a ray marching forever
# again), and only then grows it to exactly what it needed, so the next ray cast of the same view drops a
# block again. A new grid therefore gets a buffer of FRAGMENTS_PER_BLOCK rectangles per block it reserves.
FRAGMENTS_PER_BLOCK = 2


def open3d():
    """Import Open3D, the optional `scan` extra, with an install hint instead of a bare ImportError."""
    try:
        import open3d as o3d
    except ImportError:
        from ..errors import BadScanError
        raise BadScanError("scanning needs Open3D: pip install 'kinetre[scan]'") from None
    # Open3D reports buffer reallocations as warnings on stdout; only real errors matter to a user.
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    return o3d


@dataclass(frozen=True)
class Voxels:
    """Every allocated voxel of a TSDF volume.

    keys : (N, 3) int64 integer voxel coordinates (the voxel samples the point keys * voxel_size)
    tsdf : (N,) float32 truncated signed distance in [-1, 1] (positive = free space in front of the surface)
    weight : (N,) float32 number of observations (0 = never seen)
    """

    keys: np.ndarray
    tsdf: np.ndarray
    weight: np.ndarray
    voxel_size: float


class TSDFVolume:
    """A sparse TSDF with colour. `voxel_size` in metres; truncation = trunc_voxels * voxel_size."""

    def __init__(self, voxel_size: float, trunc_voxels: float = TRUNC_VOXELS, depth_max: float = 3.0,
                 block_resolution: int = 8, block_count: int = 20000):
        o3d = open3d()
        self._o3d = o3d
        self._core = o3d.core
        self.voxel_size = float(voxel_size)
        self.trunc_voxels = float(trunc_voxels)
        self.depth_max = float(depth_max)
        self._layout = (block_resolution, block_count)
        self.clear()

    def clear(self) -> None:
        """Forget everything fused so far."""
        c = self._core
        self.grid = self._o3d.t.geometry.VoxelBlockGrid(
            ("tsdf", "weight", "color"), (c.float32, c.float32, c.float32), ((1), (1), (3)),
            self.voxel_size, *self._layout, c.Device("CPU:0"))
        self.frames = 0
        self._reserve_fragments()

    def _reserve_fragments(self) -> None:
        """Grow the grid's range-rectangle buffer (FRAGMENTS_PER_BLOCK) by one small ray cast that needs that many:
        as many copies of one block, each seen as a single 2x2-pixel rectangle by a 16x16 camera (the block
        spans 1 to 2 block sizes in depth and 0 to 1 across, so its projection is the same at any voxel size)."""
        count = FRAGMENTS_PER_BLOCK * self._layout[1] + int(2 / self.voxel_size)
        keys = self._core.Tensor(np.tile(np.array([[0, 0, 1]], np.int32), (count, 1)))
        k = self._tensor(np.array([[1.0, 0.0, 4.0], [0.0, 1.0, 4.0], [0.0, 0.0, 1.0]]))
        self.grid.ray_cast(keys, k, self._tensor(np.eye(4)), 16, 16, ["depth"], 1.0, 0.1, self.depth_max, 1.0,
                           self.trunc_voxels, 1)

    # --- Open3D conversions (depth in metres everywhere, so depth_scale = 1) ---
    def _image(self, array: np.ndarray):
        return self._o3d.t.geometry.Image(self._core.Tensor(np.ascontiguousarray(array)))

    def _tensor(self, array: np.ndarray):
        return self._core.Tensor(np.ascontiguousarray(array, dtype=np.float64))

    def integrate(self, color: np.ndarray, depth: np.ndarray, camera: Intrinsics, pose: np.ndarray) -> None:
        """Fuse one frame: color (H, W, 3) uint8, depth (H, W) float32 metres, pose (4, 4) camera-to-world."""
        k = camera.matrix.copy()
        k[:2, 2] += 0.5  # Open3D truncates the projected pixel coordinate: make that a rounding
        k, extrinsic = self._tensor(k), self._tensor(np.linalg.inv(pose))
        depth_image = self._image(depth.astype(np.float32))
        color_image = self._image(color.astype(np.float32) / 255.0)
        blocks = self.grid.compute_unique_block_coordinates(depth_image, k, extrinsic, 1.0, self.depth_max,
                                                            self.trunc_voxels)
        self.grid.integrate(blocks, depth_image, color_image, k, extrinsic, 1.0, self.depth_max, self.trunc_voxels)
        self.frames += 1

    def raycast(self, camera: Intrinsics, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Render the model from `pose`: (colour (H, W, 3) float32 in [0, 1], depth (H, W) float32 metres, 0 = none).

        The raycast of the fused model is the reference that frame-to-model tracking aligns to.
        """
        out = self._raycast(camera, pose, ["depth", "color"])
        if out is None:
            return np.zeros((camera.height, camera.width, 3), np.float32), self.raycast_depth(camera, pose)
        return np.clip(out["color"], 0.0, 1.0).astype(np.float32), self._depth(out)

    def raycast_depth(self, camera: Intrinsics, pose: np.ndarray) -> np.ndarray:
        """The depth (H, W) float32 metres (0 = none) of `raycast`, without the colour (a fifth cheaper)."""
        out = self._raycast(camera, pose, ["depth"])
        return np.zeros((camera.height, camera.width), np.float32) if out is None else self._depth(out)

    def _raycast(self, camera: Intrinsics, pose: np.ndarray, attributes: list) -> dict[str, np.ndarray] | None:
        """attribute -> (H, W, C) array of the ray cast from `pose`, None when nothing is fused."""
        shifted = np.array(pose, dtype=np.float64)
        shifted[:3, 3] += 0.5 * self.voxel_size  # Open3D's ray caster is half a voxel short (module notes)
        k, extrinsic = self._tensor(camera.matrix), self._tensor(np.linalg.inv(shifted))
        blocks = self._active_blocks()
        if blocks.shape[0] == 0:
            return None
        # whole range-map tiles (RANGE_TILE): the same camera on a wider and taller image, pixel for pixel
        width, height = (-(-n // RANGE_TILE) * RANGE_TILE for n in (camera.width, camera.height))
        out = self.grid.ray_cast(blocks, k, extrinsic, width, height, attributes, 1.0, 0.1, self.depth_max,
                                 1.0, self.trunc_voxels, RANGE_TILE)
        return {name: out[name].numpy()[: camera.height, : camera.width] for name in attributes}

    @staticmethod
    def _depth(out: dict[str, np.ndarray]) -> np.ndarray:
        depth = out["depth"][..., 0].copy()
        depth[~np.isfinite(depth)] = 0.0
        return depth

    def _active_blocks(self):
        # key_tensor() spans the whole buffer capacity; only active entries are real blocks.
        hashmap = self.grid.hashmap()
        return hashmap.key_tensor()[hashmap.active_buf_indices().to(self._core.int64)]

    def voxels(self) -> Voxels:
        """All allocated voxels with their integer coordinates, TSDF and weight."""
        centres, flat = self.grid.voxel_coordinates_and_flattened_indices()
        flat = flat.numpy()
        keys = np.round(centres.numpy() / self.voxel_size).astype(np.int64)
        tsdf = self.grid.attribute("tsdf").numpy().reshape(-1)[flat]
        weight = self.grid.attribute("weight").numpy().reshape(-1)[flat]
        return Voxels(keys, tsdf.astype(np.float32), weight.astype(np.float32), self.voxel_size)

    def triangle_mesh(self, weight_threshold: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Marching cubes on the zero level set.

        Returns vertices (V, 3) float64 metres, faces (F, 3) int64, colors (V, 3) float32 in [0, 1].
        """
        if self.grid.hashmap().size() == 0:
            return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3), np.float32)
        mesh = self.grid.extract_triangle_mesh(weight_threshold=weight_threshold)
        vertices = mesh.vertex.positions.numpy().astype(np.float64)
        faces = mesh.triangle.indices.numpy().astype(np.int64) if "indices" in mesh.triangle \
            else np.zeros((0, 3), np.int64)
        colors = mesh.vertex.colors.numpy().astype(np.float32) if "colors" in mesh.vertex \
            else np.full((len(vertices), 3), 0.5, np.float32)
        return vertices, faces.reshape(-1, 3), np.clip(colors, 0.0, 1.0)
