"""`kinetre scan` subcommand: registered by kinetre.cli.scan.register, summary on stdout, errors as one line + exit 2."""
from __future__ import annotations

import argparse

import trimesh

from kinetre.cli.scan import register


def _parser():
    parser = argparse.ArgumentParser(prog="kinetre")
    register(parser.add_subparsers(dest="command"))
    return parser


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
