"""A deformation graph as ASCII PLY, for inspection in a mesh viewer (MeshLab, Blender)."""
from __future__ import annotations

from pathlib import Path

from ..errors import ExportError


def write_graph_ply(path: str, graph) -> None:
    """ASCII PLY: nodes as vertices (with normals), edges as `edge` elements with a `bridge` flag."""
    lines = ["ply", "format ascii 1.0", "comment kinetre deformation graph",
             f"element vertex {graph.node_count}", "property double x", "property double y", "property double z",
             "property double nx", "property double ny", "property double nz",
             f"element edge {len(graph.edges)}", "property int vertex1", "property int vertex2",
             "property uchar bridge", "end_header"]
    lines += [" ".join(repr(float(c)) for c in (*p, *n)) for p, n in zip(graph.nodes, graph.normals)]
    lines += [f"{a} {b} {int(br)}" for (a, b), br in zip(graph.edges.tolist(), graph.bridges.tolist())]
    try:
        Path(path).write_text("\n".join(lines) + "\n", encoding="ascii")
    except OSError as e:
        raise ExportError(f"{path}: cannot write ({e.strerror})") from None
