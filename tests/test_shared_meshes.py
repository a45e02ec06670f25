"""Every mesh in ../shared/data loads, builds one connected graph and bends without NaN."""
import networkx as nx
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import kinetre
from kinetre.skeleton.models import KINECT20, Skeleton

MESHES = ["spot.obj", "armadillo.obj", "camelhead.off", "teapot.obj", "sphereWithHole.stl",
          "elephant_loop3_large.ply.gz"]


def test_list_covers_the_folder(data_dir):
    on_disk = {p.name for p in (data_dir / "meshes").iterdir() if not p.name.endswith(".md")}
    assert on_disk == set(MESHES), "a new mesh in shared/data: add it to MESHES"


@pytest.mark.parametrize("name", MESHES)
def test_mesh_bends_without_nan(data_dir, name):
    mesh = kinetre.load_mesh(data_dir / "meshes" / name)
    graph = kinetre.build_graph(mesh, nodes=128, seed=0)
    g = nx.Graph()
    g.add_nodes_from(range(graph.node_count))
    g.add_edges_from(map(tuple, graph.edges))
    assert nx.is_connected(g)
    # a skeleton's worth of joints on the mesh: a line of joints along the longest axis
    lo, hi = mesh.bounds
    axis = int(np.argmax(hi - lo))
    order = np.argsort(graph.nodes[:, axis])
    picks = graph.nodes[order[np.linspace(0, len(order) - 1, 20).astype(int)]]
    bind = Skeleton(KINECT20, picks, np.ones(20, bool))
    # metres do not matter to the solver: attach with a reach of a tenth of the mesh size
    rig = kinetre.attach(graph, bind, reach=0.1 * mesh.diagonal, bone_radius=0.02 * mesh.diagonal)
    rot = Rotation.from_euler("xyz", [0, 0, 45], degrees=True).as_matrix()
    centre = picks.mean(axis=0)
    moved = picks.copy()
    upper = picks[:, axis] > centre[axis]
    moved[upper] = (picks[upper] - centre) @ rot.T + centre  # bend one half by 45°
    pose = rig.solve(Skeleton(KINECT20, moved, np.ones(20, bool)))
    v = kinetre.skin(mesh, graph, pose)
    assert np.all(np.isfinite(v))
    assert rig.last_report.iterations <= 10
    e = rig.last_report.energies
    assert e[-1] < e[0]
    assert np.abs(v - mesh.vertices).max() > 0.05 * mesh.diagonal  # it really bent
