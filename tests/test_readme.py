"""The README's Python example runs as printed (on the shared data, for a few frames) and writes its glTF; so does
the step-by-step example of docs/animate.md; the README's links resolve."""
import re
from pathlib import Path

import numpy as np
import pygltflib

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_example_runs(data_dir, tmp_path):
    code = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    walk = repr(str(data_dir / "bvh" / "cmu_12_01_walk.bvh"))
    assert 'kinetre.load_take("walk.bvh")' in code and '"chair_walk.glb"' in code
    code = code.replace('"chair.obj"', repr(str(data_dir / "meshes" / "spot.obj")))
    code = code.replace('kinetre.load_take("walk.bvh")', f"kinetre.load_take({walk}).slice(0, 40, 4)")
    code = code.replace('"chair_walk.glb"', repr(str(tmp_path / "spot_walk.glb")))
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    v, mesh, result = scope["vertices"], scope["mesh"], scope["result"]
    assert len(result.poses) == 10
    assert v.shape == mesh.vertices.shape and np.isfinite(v).all()
    assert np.abs(v - mesh.vertices).max() > 1e-3 * mesh.diagonal  # the cow moved
    gltf = pygltflib.GLTF2().load(str(tmp_path / "spot_walk.glb"))
    assert len(gltf.skins[0].joints) == result.graph.node_count and len(gltf.animations) == 1


def test_readme_links_resolve():
    """Every relative link of the README names a file of the repository (RESULTS.md is written by `make bench`)."""
    root = README.parent
    links = re.findall(r"\]\(([^)#]+)\)", README.read_text())
    local = [link for link in links if "://" not in link]
    assert local
    missing = [link for link in local if not (root / link).exists() and link != "benchmarks/RESULTS.md"]
    assert not missing


def test_readme_is_a_front_door():
    """At most 200 lines: the detail lives in docs/, the figures in benchmarks/RESULTS.md."""
    assert len(README.read_text().splitlines()) <= 200


def test_the_steps_inside_animate_run(data_dir):
    text = (README.parent / "docs" / "animate.md").read_text()
    code = next(b for b in re.findall(r"```python\n(.*?)```", text, re.S) if "rig.solve" in b)
    code = code.replace('"chair.obj"', repr(str(data_dir / "meshes" / "spot.obj")))
    code = code.replace('"walk.bvh"', repr(str(data_dir / "bvh" / "cmu_12_01_walk.bvh")))
    assert "range(len(take))" in code
    code = code.replace("range(len(take))", "range(0, 40, 4)")
    scope: dict = {}
    exec(compile(code, "docs/animate.md", "exec"), scope)
    v, mesh = scope["vertices"], scope["mesh"]
    assert v.shape == mesh.vertices.shape and np.isfinite(v).all()
    assert np.abs(v - mesh.vertices).max() > 1e-3 * mesh.diagonal  # the cow moved
