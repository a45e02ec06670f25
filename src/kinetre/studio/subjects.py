"""The studio's subjects, named once: where each frame, command and reply travels.

The data path, in subjects:

    capture client ──SKELETONS──▶ scene ──TRANSFORMS, STATE──▶ viewers
                    (skeleton_subject(c), one per user)        (client_subject(c): replies to one client)

Every mesh's transform blocks go on a subject of its own, `transforms_subject(id)` (TRANSFORMS matches them
all): latest-wins is per subject, so a slow viewer still gets every mesh's newest block.

With the scene in its own process (remote.py), a gateway forwards each page's commands on
`command_subject(c)` and asks the scene for files, uploads, upload jobs, takes and mesh removals on FILES,
UPLOAD, JOBS, TAKES and MESHES. Names follow NATS syntax (dot-separated tokens, `*` one token); a NATS bus
maps them into one room on the wire by putting the room after the namespace (natsbus.py).
"""
from __future__ import annotations

NAMESPACE = "kinetre."
SKELETON_PREFIX = NAMESPACE + "skeleton."
SKELETONS = SKELETON_PREFIX + "*"
TRANSFORMS_PREFIX = NAMESPACE + "transforms."
TRANSFORMS = TRANSFORMS_PREFIX + "*"
STATE = NAMESPACE + "state"
CLIENT_PREFIX = NAMESPACE + "client."
COMMAND_PREFIX = NAMESPACE + "command."
COMMANDS = COMMAND_PREFIX + "*"
FILES = NAMESPACE + "files"  # request: a chunk of a mesh payload or a take file
UPLOAD = NAMESPACE + "upload"  # request: a chunk of an uploaded mesh
JOBS = NAMESPACE + "jobs"  # request: an upload job's progress
TAKES = NAMESPACE + "takes"  # request: stop recording and export the take
MESHES = NAMESPACE + "meshes"  # request: remove a mesh

# The second token says how a subject is delivered: live ones latest-wins (a slow reader gets the newest
# frame), queued ones message by message (every reply must reach its page, every command its scene).
LIVE_KINDS = ("skeleton", "transforms", "state")
QUEUED_KINDS = ("client", "command")


def skeleton_subject(client: str) -> str:
    """The subject a capture client's (or a player's) skeleton frames go on: one per user, under SKELETONS."""
    return SKELETON_PREFIX + client


def transforms_subject(mesh_id: int) -> str:
    """The subject of mesh `mesh_id`'s transform blocks."""
    return f"{TRANSFORMS_PREFIX}{int(mesh_id)}"


def is_transforms(subject: str) -> bool:
    """Whether `subject` carries transform blocks (a `transforms_subject`)."""
    return subject.startswith(TRANSFORMS_PREFIX)


def client_subject(client: str) -> str:
    """The subject of replies meant for one client only (errors, acknowledgements)."""
    return CLIENT_PREFIX + client


def command_subject(client: str) -> str:
    """The subject of one client's commands to a scene in another process."""
    return COMMAND_PREFIX + client


def kind(subject: str) -> str:
    """"kinetre.skeleton.c3" → "skeleton"."""
    return subject.split(".")[1] if subject.count(".") else ""


def last_token(subject: str) -> str:
    """The client a per-client subject belongs to: "kinetre.skeleton.c3" → "c3"."""
    return subject.rsplit(".", 1)[-1]
