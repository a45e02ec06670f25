"""`kinetre studio [MESH]`: the live studio server, opened in a browser."""
from __future__ import annotations

from .common import add_room_options, room_token


def register(sub) -> None:
    """Add `kinetre studio` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("studio", help="the live studio in a browser")
    p.add_argument("mesh", nargs="?", default=None, help="mesh to open (default: the bundled Spot)")
    p.add_argument("--port", type=int, default=8000)
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser")
    add_room_options(p)
    p.add_argument("--remote-scene", action="store_true",
                   help="no scene in this server: a `kinetre scene` process on the same NATS room solves")
    p.set_defaults(func=cmd_studio)


def cmd_studio(args) -> int:
    from ..studio.app import run_studio
    run_studio(args.mesh, host=args.host, port=args.port, open_browser=not args.no_browser, nats=args.nats,
               room=args.room, token=room_token(args), remote_scene=args.remote_scene, nkey=args.nkey)
    return 0
