"""`kinetre scene [MESH] --nats URL`: a headless scene that solves a room's skeletons over NATS."""
from __future__ import annotations

from .common import UsageError, add_live_cleanup_options, add_room_options, live_cleanup, room_token


def register(sub) -> None:
    """Add `kinetre scene` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("scene", help="a headless scene: solves a room's skeletons over NATS, publishes transforms")
    p.add_argument("mesh", nargs="?", default=None, help="mesh to load (default: the bundled Spot)")
    p.add_argument("--nodes", type=int, default=128, help="graph nodes (default 128)")
    p.add_argument("--sample", action="store_true", help="play the bundled walk as a capture client")
    add_live_cleanup_options(p)
    add_room_options(p)
    p.set_defaults(func=cmd_scene)


def cmd_scene(args) -> int:
    from ..studio.remote import run_scene
    if not args.nats:
        raise UsageError("kinetre scene needs --nats URL: it talks to studios only through a NATS server")
    run_scene(args.mesh, args.nats, room=args.room, token=room_token(args), nodes=args.nodes,
              sample_motion=args.sample, nkey=args.nkey, **live_cleanup(args))
    return 0
