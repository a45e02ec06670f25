"""`kinetre scan` subcommand: registered by kinetre.cli.scan.register, summary on stdout, errors as one line + exit 2."""
from __future__ import annotations

import argparse

import pytest
import trimesh

from kinetre.cli.scan import register


def _parser():
    parser = argparse.ArgumentParser(prog="kinetre")
    register(parser.add_subparsers(dest="command"))
    return parser


@pytest.mark.slow
def test_scan_command_writes_mesh_and_summary(tiny_frames, tmp_path, capsys):
    out = tmp_path / "tiny.obj"
    args = _parser().parse_args(["scan", str(tiny_frames), "-o", str(out), "--voxel", "0.02", "--faces", "500",
                                 "--quiet"])
    assert args.func(args) == 0
    summary = capsys.readouterr().out.strip().splitlines()[-1]
    assert summary.startswith("scan: 3 frames used, 0 rejected,") and summary.endswith(str(out))
    mesh = trimesh.load(out, force="mesh", process=False)
    assert 0 < len(mesh.faces) <= 500
    assert f"{len(mesh.vertices)} vertices" in summary


def test_scan_command_bad_input_is_one_line_exit_2(tmp_path, capsys):
    args = _parser().parse_args(["scan", str(tmp_path), "-o", str(tmp_path / "x.ply"), "--quiet"])
    assert args.func(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no RGB-D frames" in err
    args = _parser().parse_args(["scan", str(tmp_path), "-o", str(tmp_path / "x.ply"), "--segment", "change"])
    assert args.func(args) == 2
    assert "--before" in capsys.readouterr().err


def test_scan_and_animate_take_the_same_scan_options():
    from kinetre.cli.animate import register as register_animate
    parser = argparse.ArgumentParser(prog="kinetre")
    sub = parser.add_subparsers(dest="command")
    register(sub)
    register_animate(sub)

    def scan_group(name):
        group = next(g for g in sub.choices[name]._action_groups if g.title == "RGB-D frames")
        return {a.dest: (tuple(a.option_strings), a.help.replace(f"(default {a.default})", ""), a.choices)
                for a in group._group_actions}

    assert scan_group("scan") == scan_group("animate")
    assert {"segment", "before", "voxel", "intrinsics", "camera", "depth_scale", "depth_max", "faces"} <= \
        set(scan_group("scan"))
    scan = parser.parse_args(["scan", "f/", "-o", "x.ply", "--faces", "500", "--depth-max", "2"])
    animate = parser.parse_args(["animate", "f/", "--motion", "w.bvh", "-o", "x.glb", "--faces", "500",
                                 "--depth-max", "2"])
    from kinetre.cli.common import scan_options
    assert scan_options(scan) == {"segment": None, "before": None, "target_faces": 500, "depth_max": 2.0}
    assert scan_options(animate) == {**scan_options(scan), "segment": "plane"}
