"""The up axis found on load (kinetre.mesh.upright): how often it is right, and what it costs.

Every mesh in ../shared/data/meshes (but the ball, which has no up) and every avatar skinned in its bind
pose and half a second into its first clip, written as a mesh without a convention (.ply): each is stood on
each of the six axis directions, square and leaning 8 degrees about a random level axis, and the axis found
is compared with the one its up was turned to. Then the CPU time of one call on the 386k-vertex elephant.

Prints one JSON object per line: per mesh, the orientations right of 6 (square, leaning); then the totals.
"""
from __future__ import annotations

import time

import numpy as np

from scipy.spatial.transform import Rotation

from bench_core import DATA, emit
from kinetre.avatar.load import load_avatar
from kinetre.avatar.skin import posed_mesh
from kinetre.gltf_read import read_gltf
from kinetre.mesh.load import load_mesh
from kinetre.mesh.mesh import Mesh
from kinetre.mesh.upright import AXES, find_upright, rotation_to_y_up
from kinetre.motion.gltf import world_matrices

MESHES = ("spot.obj", "armadillo.obj", "camelhead.off", "teapot.obj", "elephant_loop3_large.ply.gz")
AVATARS = ("CesiumMan.glb", "Fox.glb", "RiggedFigure.glb", "robot_quaternius.glb")
LEAN = 8.0


def upright_meshes():
    """(label, mesh standing +Y up) for every case."""
    for name in MESHES:
        yield name, load_mesh(DATA / "meshes" / name)
    for name in AVATARS:
        path = DATA / "avatars" / name
        avatar = load_avatar(path)
        yield f"{name} bind", posed_mesh(avatar, avatar.bind_world)
        doc = read_gltf(path)
        if doc.doc.animations:
            world = world_matrices(doc, 0, np.array([0.5]))[0][avatar.joints]
            yield f"{name} posed", posed_mesh(avatar, world)


def stored_with_up(mesh: Mesh, up: str, lean: np.ndarray) -> Mesh:
    """The standing mesh leant by `lean` and stored with its up along the axis `up`."""
    turn = rotation_to_y_up(up).T @ lean
    return Mesh(vertices=mesh.vertices @ turn.T, faces=mesh.faces, normals=mesh.normals @ turn.T)


def accuracy(find=find_upright) -> None:
    """Emit the per-mesh rows and the totals for the up-axis finder `find(mesh, path)`."""
    rng = np.random.default_rng(0)
    right = {0.0: 0, LEAN: 0}
    cases = 0
    for label, mesh in upright_meshes():
        row = {"bench": "upright_accuracy", "mesh": label, "vertices": len(mesh.vertices)}
        for lean_deg in (0.0, LEAN):
            found = []
            for up in AXES:
                level = rng.normal(size=3)
                level[1] = 0.0
                lean = Rotation.from_rotvec(np.radians(lean_deg) * level / np.linalg.norm(level)).as_matrix()
                found.append(find(stored_with_up(mesh, up, lean), "stored.ply").up)
            ok = sum(f == up for f, up in zip(found, AXES))
            right[lean_deg] += ok
            row["square_of_6" if lean_deg == 0 else "leaning_of_6"] = ok
            row["found_square" if lean_deg == 0 else "found_leaning"] = " ".join(found)
        cases += len(AXES)
        emit(row)
    emit({"bench": "upright_accuracy", "mesh": "all", "square": f"{right[0.0]}/{cases}",
          "leaning": f"{right[LEAN]}/{cases}", "axes_tried": " ".join(AXES)})


def main() -> None:
    accuracy()
    elephant = load_mesh(DATA / "meshes" / "elephant_loop3_large.ply.gz")
    find_upright(elephant, "elephant.ply")  # the compiled kernel loaded
    runs = []
    for _ in range(5):
        c = time.process_time()
        find_upright(elephant, "elephant.ply")
        runs.append(time.process_time() - c)
    emit({"bench": "upright_time", "vertices": len(elephant.vertices), "cpu_s_median": round(float(np.median(runs)), 3),
          "cpu_s_min": round(min(runs), 3)})


if __name__ == "__main__":
    main()
