"""The `kinetre` command line: each subcommand on real data, and one clear line + exit 2 for bad input."""
from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pygltflib
import pytest
import trimesh

import kinetre
from kinetre.cli import main
from kinetre.motion.bvh import load_bvh
from kinetre.motion.stream import read_stream

J = kinetre.KINECT20.index


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def bad(capsys, *argv) -> str:
    code, out, err = run(capsys, *argv)
    lines = err.strip().splitlines()
    assert code == 2, f"exit {code}, stderr {err!r}"
    assert len(lines) == 1 and lines[0].startswith("kinetre: error: "), err
    return lines[0]


@pytest.fixture(scope="module")
def spot(data_dir):
    return data_dir / "meshes" / "spot.obj"


def test_help_lists_commands_and_examples():
    proc = subprocess.run([sys.executable, "-m", "kinetre.cli", "--help"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0
    for word in ("animate", "capture", "record", "info", "graph", "studio", "scan", "examples:",
                 "kinetre animate chair.obj --motion walk.bvh -o chair_walk.glb"):
        assert word in proc.stdout
    with pytest.raises(SystemExit) as e:
        main(["animate", "--help"])
    assert e.value.code == 0


def test_parser_and_argument_errors_import_no_engine():
    # `kinetre --help` and a bad argument answer without loading numba, scipy or trimesh (kinetre.lazy)
    probe = ("import sys\nfrom kinetre.cli import main\ntry:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
             "print(sorted(m for m in ('numba', 'scipy', 'trimesh', 'kinetre.mesh.load') if m in sys.modules))")
    for argv in (["--help"], ["animate", "mesh.obj"]):  # the second lacks --motion and -o
        proc = subprocess.run([sys.executable, "-c", probe, *argv], capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr
        assert proc.stdout.strip().splitlines()[-1] == "[]"
    import kinetre as package
    assert package.load_mesh is kinetre.mesh.load.load_mesh and "attach" in dir(package)


def test_info_on_each_kind(capsys, data_dir, spot):
    code, out, _ = run(capsys, "info", spot)
    assert code == 0 and "mesh, 3225 vertices, 5856 faces" in out and "UVs: yes" in out
    code, out, _ = run(capsys, "info", data_dir / "bvh" / "cmu_01_01_hops.bvh")
    assert code == 0 and "31 joints + 7 end sites, 96 channels, 2752 frames at 120 fps" in out
    assert "HipLeft <- LeftUpLeg (name)" in out and "unit: cmu" in out
    code, out, _ = run(capsys, "info", data_dir / "video" / "pose_1.mp4")
    assert code == 0 and "576x576, 120 frames at 30 fps" in out


def test_graph_ply(capsys, tmp_path, spot):
    out_path = tmp_path / "g.ply"
    code, out, _ = run(capsys, "graph", spot, "--nodes", 64, "-o", out_path)
    assert code == 0
    ply = trimesh.load(out_path, process=False)  # vertices: the nodes, read back by a PLY reader
    text = out_path.read_text().splitlines()
    n = int(next(l for l in text if l.startswith("element vertex")).split()[-1])
    e = int(next(l for l in text if l.startswith("element edge")).split()[-1])
    assert 0.9 * 64 <= n <= 1.1 * 64 and len(ply.vertices) == n
    edges = np.array([l.split() for l in text[-e:]], dtype=int)
    assert edges[:, :2].min() >= 0 and edges[:, :2].max() < n and set(edges[:, 2]) <= {0, 1}
    graph = kinetre.build_graph(kinetre.load_mesh(spot), nodes=64, seed=0)
    np.testing.assert_array_equal(edges[:, :2], graph.edges)
    np.testing.assert_array_equal(edges[:, 2].astype(bool), graph.bridges)
    np.testing.assert_array_equal(np.asarray(ply.vertices), graph.nodes)  # repr floats: exact
    assert f"{n} nodes, {e} edges" in out


def test_animate_to_a_take_places_the_skeleton_on_the_mesh(capsys, tmp_path, data_dir, spot):
    out_path = tmp_path / "spot_walk.kinetre.jsonl"
    code, out, err = run(capsys, "animate", spot, "--motion", data_dir / "bvh" / "cmu_12_01_walk.bvh",
                         "-o", out_path, "--nodes", 64, "--max-frames", 12)
    assert code == 0, err
    assert re.search(r"attached \d+ joint\(s\) \(.+\), \d+ bone samples, \d+ of \d+ nodes", out), out
    take = read_stream(out_path)
    mesh = kinetre.load_mesh(spot)
    lo, hi = mesh.bounds
    assert len(take) == 12 and take.fps == pytest.approx(30.0)
    bind = take.frame(0)
    # scaled to the mesh height, grounded at its lowest point, centred in x/z
    assert bind.height == pytest.approx(hi[1] - lo[1], rel=1e-9)
    assert bind.positions[:, 1].min() == pytest.approx(lo[1], abs=1e-9)
    mid = 0.5 * (bind.positions.min(axis=0) + bind.positions.max(axis=0))
    np.testing.assert_allclose(mid[[0, 2]], (0.5 * (lo + hi))[[0, 2]], atol=1e-9)


def test_animate_stands_a_z_up_mesh_and_says_why(capsys, tmp_path, data_dir, spot):
    mesh = kinetre.load_mesh(spot)
    lying = tmp_path / "lying.obj"
    trimesh.Trimesh(mesh.vertices @ np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]).T, mesh.faces,
                    process=False).export(lying)  # a quarter turn about +X: stored +Z up
    walk = data_dir / "bvh" / "cmu_12_01_walk.bvh"
    heights = {}
    for up, said in (("auto", "up: stood up: +Z up, it stands better than with +Y up"), ("y", "up: +Y up, as asked")):
        out_path = tmp_path / f"{up}.kinetre.jsonl"
        code, out, err = run(capsys, "animate", lying, "--motion", walk, "--up", up, "--nodes", 48,
                             "--max-frames", 2, "-o", out_path)
        assert code == 0, err
        assert said in out.splitlines()
        heights[up] = read_stream(out_path).frame(0).height
    lo, hi = mesh.bounds
    assert heights["auto"] == pytest.approx(hi[1] - lo[1], rel=1e-6)  # sized to the standing cow
    assert heights["y"] == pytest.approx(hi[2] - lo[2], rel=1e-6)     # to the lying one, as asked
    assert "--up must be one of auto, y, z, x, -x, -y, -z, got 'w'" in bad(
        capsys, "animate", lying, "--motion", walk, "--up", "w", "-o", tmp_path / "x.glb")


def test_animate_glb(capsys, tmp_path, data_dir, spot):
    out_path = tmp_path / "spot.glb"
    code, out, err = run(capsys, "animate", spot, "--motion", data_dir / "bvh" / "mixamo_rig_freebvh.bvh",
                         "-o", out_path, "--nodes", 64, "--max-frames", 6, "--subset", "legs,HipCenter")
    assert code == 0, err
    assert "solved 6 frames" in out
    doc = pygltflib.GLTF2().load(str(out_path))
    assert len(doc.skins) == 1 and len(doc.animations) == 1
    joints = len(doc.skins[0].joints)
    assert 0.9 * 64 <= joints <= 1.1 * 64
    times = doc.accessors[doc.animations[0].samplers[0].input]
    assert times.count == 6 and times.max[0] == pytest.approx(5 / 30)


def test_animate_bvh_output_rereads(capsys, tmp_path, data_dir, spot):
    a, b = tmp_path / "a.kinetre.jsonl", tmp_path / "b.bvh"
    args = [spot, "--motion", data_dir / "bvh" / "pybvh_test1.bvh", "--nodes", 48, "--frames", "10:20", "-q"]
    assert run(capsys, "animate", *args, "-o", a)[0] == 0
    assert run(capsys, "animate", *args, "-o", b)[0] == 0
    ta, tb = read_stream(a), load_bvh(b)
    assert len(ta) == len(tb) == 10 and tb.model is kinetre.KINECT20
    assert np.abs(ta.positions - tb.positions).max() < 1e-5


def test_record_and_capture(capsys, tmp_path, data_dir):
    out_path = tmp_path / "walk.kinetre.jsonl"
    code, out, _ = run(capsys, "record", data_dir / "bvh" / "cmu_12_01_walk.bvh", "--fps", 30, "-o", out_path)
    assert code == 0 and "kinect20, 20 joints, 131 frames at 30 fps" in out
    direct = load_bvh(data_dir / "bvh" / "cmu_12_01_walk.bvh")
    assert np.array_equal(read_stream(out_path).positions, direct.positions[::4])
    cap = tmp_path / "dance.kinetre.jsonl"
    code, out, err = run(capsys, "capture", "--video", data_dir / "video" / "pose_1.mp4", "--max-frames", 8,
                         "-q", "-o", cap)
    assert code == 0, err
    take = read_stream(cap)
    assert len(take) == 8 and take.tracked.mean() > 0.9


def test_bad_inputs_give_one_line_and_exit_2(capsys, tmp_path, data_dir, spot):
    corrupt = tmp_path / "corrupt.bvh"
    corrupt.write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    assert "corrupt.bvh: line 1: not a BVH file" in bad(capsys, "info", corrupt)
    text = (data_dir / "bvh" / "mocapbank_test.bvh").read_text()
    no_motion = tmp_path / "no_motion.bvh"
    no_motion.write_text(text.split("MOTION")[0])
    assert "no_motion.bvh: no MOTION section" in bad(capsys, "animate", spot, "--motion", no_motion,
                                                      "-o", tmp_path / "x.glb")
    lines = text.splitlines()
    lines[130] += " 0.0"
    wrong = tmp_path / "wrong_channels.bvh"
    wrong.write_text("\n".join(lines))
    assert "wrong_channels.bvh: line 131: expected 60 channel values" in bad(
        capsys, "record", wrong, "-o", tmp_path / "w.kinetre.jsonl")
    assert "missing.obj" in bad(capsys, "info", tmp_path / "missing.obj")
    assert "unsupported output type" in bad(capsys, "animate", spot, "--motion", corrupt, "-o", tmp_path / "x.abc")
    blank = tmp_path / "blank.mp4"
    import cv2
    w = cv2.VideoWriter(str(blank), cv2.VideoWriter_fourcc(*"mp4v"), 10, (96, 96))
    for i in range(4):
        w.write(np.full((96, 96, 3), 200, np.uint8))
    w.release()
    assert "blank.mp4: no person found in any of the 4 frames" in bad(
        capsys, "capture", "--video", blank, "-o", tmp_path / "b.kinetre.jsonl")
    assert "camera 99: cannot open" in bad(capsys, "capture", "--camera", 99, "-o", tmp_path / "cam.kinetre.jsonl")
    assert not (tmp_path / "cam.kinetre.jsonl").exists()
    assert "--frames must be START:END" in bad(capsys, "animate", spot, "--motion", no_motion, "--frames", "5",
                                               "-o", tmp_path / "x.glb")


def test_nothing_attaches(capsys, tmp_path, data_dir):
    # two small balls 1.6 apart: the skeleton spans them, but its elbow and knee are far from both
    balls = trimesh.util.concatenate([trimesh.creation.icosphere(radius=0.08).apply_translation((0, y, 0))
                                      for y in (0.08, 1.68)])
    path = tmp_path / "dumbbell.ply"
    balls.export(path)
    msg = bad(capsys, "animate", path, "--motion", data_dir / "bvh" / "mocapbank_test.bvh",
              "--subset", "ElbowLeft,KneeRight",
              "--nodes", 32, "-o", tmp_path / "x.glb")
    assert "cannot possess" in msg


def test_studio_and_scan_are_registered():
    for cmd in ("studio", "scan"):
        with pytest.raises(SystemExit) as e:
            main([cmd, "--help"])
        assert e.value.code == 0


ANIMAL = """HIERARCHY
ROOT Body
{
  OFFSET 0 60 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Neck
  { OFFSET 0 10 40
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    { OFFSET 0 20 20 } }
  JOINT Tail
  { OFFSET 0 5 -40
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    { OFFSET 0 -10 -30 } }
  JOINT FrontLeg
  { OFFSET 15 -5 30
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    { OFFSET 0 -55 0 } }
  JOINT BackLeg
  { OFFSET 15 -5 -30
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    { OFFSET 0 -55 0 } }
}
MOTION
Frames: 4
Frame Time: 0.0333333
0 60 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0
0 60 2 0 0 0 10 0 0 0 0 0 0 20 0 0 -20 0
0 60 4 0 0 0 20 0 0 0 0 0 0 40 0 0 -40 0
0 60 6 0 0 0 10 0 0 0 0 0 0 20 0 0 -20 0
"""


def test_an_animal_bvh_drives_a_mesh_by_its_own_bones(capsys, tmp_path, data_dir):
    bvh = tmp_path / "animal.bvh"
    bvh.write_text(ANIMAL)
    out_path = tmp_path / "cow.kinetre.jsonl"
    code, out, err = run(capsys, "animate", data_dir / "meshes" / "spot.obj", "--motion", bvh, "--nodes", 48,
                         "-o", out_path)
    assert code == 0, err
    assert "bvh:animal, 9 joints, 4 frames" in out
    take = read_stream(out_path)
    assert take.model.name == "bvh:animal" and "FrontLeg_End" in take.model.joints
    # the legs swing: the front paw moves between frames 0 and 2
    paw = take.positions[:, take.model.joints.index("FrontLeg_End")]
    assert np.linalg.norm(paw[2] - paw[0]) > 0.05
