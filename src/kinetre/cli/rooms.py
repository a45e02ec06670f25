"""`kinetre rooms ROOM=SECRET... -o nats.conf`: a nats-server configuration, one user per room."""
from __future__ import annotations

from pathlib import Path

from .common import UsageError


def register(sub) -> None:
    """Add `kinetre rooms` to the `kinetre` parser's subcommands."""
    p = sub.add_parser("rooms", help="write a nats-server configuration: one user per room, confined to its subjects")
    p.add_argument("rooms", nargs="+", metavar="ROOM=SECRET",
                   help="ROOM=TOKEN (a password) or ROOM=@FILE (an nkey seed file; a new one is made if missing)")
    p.add_argument("-o", "--output", required=True, help="the configuration file to write (nats-server -c FILE)")
    p.add_argument("--port", type=int, default=4222, help="the port nats-server listens on (default 4222)")
    p.add_argument("--host", default="127.0.0.1", help="the address nats-server binds (default 127.0.0.1)")
    p.add_argument("-q", "--quiet", action="store_true")
    p.set_defaults(func=cmd_rooms)


def cmd_rooms(args) -> int:
    """Write a nats-server configuration for the given rooms (each `ROOM=TOKEN` or `ROOM=@SEED_FILE`)."""
    from ..studio.natsbus import check_room, nkey_public, room_nkey, server_config
    rooms: dict[str, str] = {}
    for spec in args.rooms:
        room, sep, secret = spec.partition("=")
        if not sep or not room or not secret:
            raise UsageError(f"{spec!r}: a room is ROOM=TOKEN or ROOM=@SEED_FILE (an nkey seed, made if missing)")
        check_room(room)  # before a seed file is made for it
        if room in rooms:
            raise UsageError(f"room {room!r} is given twice")
        if secret.startswith("@"):
            seed = Path(secret[1:])
            made = not seed.exists()
            rooms[room] = room_nkey(seed) if made else nkey_public(seed)
            if not args.quiet:
                print(f"room {room}: nkey {rooms[room]} ({'new seed written to' if made else 'seed in'} {seed}:"
                      f" give it to the room's studios and scene as --nkey {seed})")
        else:
            rooms[room] = secret
    text = server_config(rooms, args.port, host=args.host)
    try:
        Path(args.output).write_text(text)
    except OSError as e:
        raise UsageError(f"{args.output}: cannot write ({e.strerror})") from None
    if not args.quiet:
        print(f"wrote {args.output}: run nats-server -c {args.output}")
    return 0
