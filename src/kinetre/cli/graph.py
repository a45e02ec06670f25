"""`kinetre graph MESH -o graph.ply`: a mesh's deformation graph, written for inspection."""
from __future__ import annotations

from ..export.ply import write_graph_ply
from .common import output_ext


def register(sub) -> None:
    """Add `kinetre graph` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("graph", help="build a mesh's deformation graph and write it as PLY for inspection")
    p.add_argument("mesh")
    p.add_argument("-o", "--output", required=True, help="output .ply (nodes = vertices, edges with a bridge flag)")
    p.add_argument("--nodes", type=int, default=128)
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_graph)


def cmd_graph(args) -> int:
    import kinetre
    output_ext(args.output, (".ply",))
    mesh = kinetre.load_mesh(args.mesh)
    graph = kinetre.build_graph(mesh, nodes=args.nodes, seed=args.seed)
    write_graph_ply(args.output, graph)
    print(f"wrote {args.output}: {graph.node_count} nodes, {len(graph.edges)} edges "
          f"({int(graph.bridges.sum())} rigid/bridge), radius {graph.radius:.4g}")
    return 0
