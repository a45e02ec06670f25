"""trimesh is imported with the modules it loads for features kinetre never calls deferred (kinetre.lazy):
they run only when first used, and then work as usual."""
from __future__ import annotations

import subprocess
import sys

PROBE = """
import sys
from kinetre.lazy import TRIMESH_UNUSED, import_trimesh
from kinetre.mesh.load import load_mesh
mesh = load_mesh(sys.argv[1])
# scipy.optimize's package code (which imports its submodules) has not run, nor trimesh's bounding spheres'
print(sorted(m for m in ("scipy.optimize._minimize", "scipy.ndimage._filters") if m in sys.modules))
trimesh = import_trimesh()
sphere = trimesh.creation.icosphere(subdivisions=2, radius=2.5)
center, radius = trimesh.nsphere.minimum_nsphere(sphere)  # first use: the deferred modules load and run
print(round(float(radius), 6), "scipy.optimize._minimize" in sys.modules, len(mesh.vertices))
from scipy import ndimage
print(int(ndimage.label([[1, 0, 1]])[1]))
"""


def test_deferred_modules_load_on_first_use(data_dir):
    spot = data_dir / "meshes" / "spot.obj"
    proc = subprocess.run([sys.executable, "-c", PROBE, str(spot)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert lines[-3] == "[]"
    assert lines[-2] == "2.5 True 3225"
    assert lines[-1] == "2"
