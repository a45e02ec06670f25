"""`kinetre studio [MESH]`: the live studio server, opened in a browser."""
from __future__ import annotations

from .common import UsageError, add_live_cleanup_options, add_room_options, live_cleanup, room_token


def register(sub) -> None:
    """Add `kinetre studio` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("studio", help="the live studio in a browser")
    p.add_argument("mesh", nargs="?", default=None, help="mesh to open (default: the bundled Spot)")
    p.add_argument("--port", type=int, default=8000)
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser")
    add_live_cleanup_options(p)
    add_room_options(p)
    p.add_argument("--remote-scene", action="store_true",
                   help="no scene in this server: a `kinetre scene` process on the same NATS room solves")
    p.add_argument("--vmc", default=None, metavar="HOST:PORT",
                   help="every avatar sends its live pose as VMC (avatar n to PORT + n - 1; docs/vmc.md)")
    p.add_argument("--vmc-listen", default=None, metavar="[HOST:]PORT",
                   help="VMC performers sending here (UDP, 127.0.0.1 by default) become users who possess the mesh")
    p.set_defaults(func=cmd_studio)


def _models_for_the_page() -> None:
    """The page tracks a webcam with the MediaPipe models: fetched on first use; without them the studio
    still plays clips, so a failed fetch is a warning."""
    import sys

    from ..errors import KinetreError
    from ..motion.fetch_models import ensure_models
    try:
        ensure_models()
    except KinetreError as e:
        print(f"kinetre: warning: {' '.join(str(e).split())}; until then the page cannot track a camera",
              file=sys.stderr)


def cmd_studio(args) -> int:
    from ..studio.app import run_studio
    from ..vmc.receive import listen_address
    from ..vmc.send import VmcSender, parse_address
    vmc = None
    if args.vmc is not None:
        vmc = parse_address(args.vmc)
        VmcSender(*vmc).close()                    # an address that does not resolve fails now, not per frame
    vmc_listen = listen_address(args.vmc_listen) if args.vmc_listen is not None else None
    cleanup = live_cleanup(args)
    if args.remote_scene and (args.raw or args.contact):
        raise UsageError("--raw and --contact apply where the scene solves: give them to `kinetre scene`")
    _models_for_the_page()
    run_studio(args.mesh, host=args.host, port=args.port, open_browser=not args.no_browser, nats=args.nats,
               room=args.room, token=room_token(args), remote_scene=args.remote_scene, nkey=args.nkey, vmc=vmc,
               vmc_listen=vmc_listen, **cleanup)
    return 0
