"""The README's Python example runs as printed (on the shared data, for a few frames)."""
import re
from pathlib import Path

import numpy as np


def test_readme_example_runs(data_dir):
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    code = code.replace('"chair.obj"', repr(str(data_dir / "meshes" / "spot.obj")))
    code = code.replace('"walk.bvh"', repr(str(data_dir / "bvh" / "cmu_12_01_walk.bvh")))
    assert "range(len(take))" in code
    code = code.replace("range(len(take))", "range(0, 40, 4)")
    scope: dict = {}
    exec(compile(code, "README.md", "exec"), scope)
    v, mesh = scope["vertices"], scope["mesh"]
    assert v.shape == mesh.vertices.shape and np.isfinite(v).all()
    assert np.abs(v - mesh.vertices).max() > 1e-3 * mesh.diagonal  # the cow moved
