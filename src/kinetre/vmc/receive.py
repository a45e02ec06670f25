"""VMC protocol in: a performer's `/VMC/Ext/Root/Pos` and `/VMC/Ext/Bone/Pos` messages as Kinect-20 skeletons.

Each `Bone/Pos` carries a Unity HumanBodyBones name, a local position and a local rotation (x, y, z, w) in
Unity's left-handed axes, relative to the bone's parent in Unity's humanoid hierarchy (`UNITY_PARENTS`);
`Root/Pos` places the whole avatar. A performer may send every bone (chest, shoulders, fingers...) or a
subset; a bone is composed onto its nearest ancestor that was sent. The local transforms are mirrored into
Kinetre's right-handed frame (x → −x: positions (−x, y, z), quaternions (x, −y, −z, w); the avatar then faces
+Z with its left on +X, as a person facing the camera does) and composed down the hierarchy into joint
positions, which the one skeleton mapper (skeleton/humanoid_map.py, by the bones' VRM names) turns into
Kinect-20 joints.

A frame is complete at the end of an OSC bundle that moved a bone, or, for a performer that sends loose
messages, at its `/VMC/Ext/T` or `/VMC/Ext/Blend/Apply` (both sent once per frame).

Face: `/VMC/Ext/Blend/Val` (name, weight) values take effect at the next `/VMC/Ext/Blend/Apply`, as in a VMC
receiver; the applied clips become MediaPipe's blendshapes (`avatar.expressions.blendshapes_from_clips`:
ARKit names as they are, VRM presets such as A, Blink_L, Joy onto the blendshapes they stand for), carried
with every frame from then on.
"""
from __future__ import annotations

import numpy as np

from ..avatar.expressions import blendshapes_from_clips
from ..avatar.normalized import vrm_name
from ..rotation import quaternion_matrices
from ..skeleton.mediapipe import BLENDSHAPES
from ..skeleton.humanoid_map import kinect_frames, map_humanoid
from ..skeleton.models import KINECT20, Skeleton

_CHAINS = {"Hips": None, "Spine": "Hips", "Chest": "Spine", "UpperChest": "Chest", "Neck": "UpperChest",
           "Head": "Neck", "LeftEye": "Head", "RightEye": "Head", "Jaw": "Head"}
for _side in ("Left", "Right"):
    _CHAINS.update({f"{_side}UpperLeg": "Hips", f"{_side}LowerLeg": f"{_side}UpperLeg",
                    f"{_side}Foot": f"{_side}LowerLeg", f"{_side}Toes": f"{_side}Foot",
                    f"{_side}Shoulder": "UpperChest", f"{_side}UpperArm": f"{_side}Shoulder",
                    f"{_side}LowerArm": f"{_side}UpperArm", f"{_side}Hand": f"{_side}LowerArm"})
    for _finger in ("Thumb", "Index", "Middle", "Ring", "Little"):
        _CHAINS.update({f"{_side}{_finger}Proximal": f"{_side}Hand",
                        f"{_side}{_finger}Intermediate": f"{_side}{_finger}Proximal",
                        f"{_side}{_finger}Distal": f"{_side}{_finger}Intermediate"})
UNITY_PARENTS = dict(_CHAINS)  # Unity HumanBodyBones name -> its parent bone (None for the hips)
_ORDER = {name: k for k, name in enumerate(UNITY_PARENTS)}   # parents before children
SIGNS = np.array([1.0, -1.0, -1.0, 1.0])  # Unity quaternion <-> right-handed, mirrored in x


def _rotation(q) -> np.ndarray:
    """A sent quaternion (x, y, z, w) as a 3x3 rotation; a zero or non-finite one is the identity."""
    q = np.asarray(q, dtype=np.float64)
    return quaternion_matrices(q) if np.isfinite(q).all() and q @ q > 1e-12 else np.eye(3)


def _parent_sent(name: str, sent) -> str | None:
    p = UNITY_PARENTS[name]
    while p is not None and p not in sent:
        p = UNITY_PARENTS[p]
    return p


def world_positions(bones: dict, root=None) -> tuple[tuple[str, ...], list[int], np.ndarray]:
    """Compose `bones` (Unity name -> (position (3,), quaternion (4,)), Unity axes) under `root` (the same pair,
    or None) into right-handed world joint positions: (names, parents, (J, 3) positions)."""
    names = tuple(sorted((n for n in bones if n in UNITY_PARENTS), key=_ORDER.__getitem__))
    mirror = np.array([-1.0, 1.0, 1.0])
    if root is None:
        base_r, base_t = np.eye(3), np.zeros(3)
    else:
        base_r, base_t = _rotation(np.asarray(root[1]) * SIGNS), np.asarray(root[0]) * mirror
    rot, pos, parents = {}, {}, []
    for name in names:
        p_local, q_local = bones[name]
        r = _rotation(np.asarray(q_local) * SIGNS)
        t = np.asarray(p_local, dtype=np.float64) * mirror
        parent = _parent_sent(name, bones)
        pr, pt = (base_r, base_t) if parent is None else (rot[parent], pos[parent])
        rot[name], pos[name] = pr @ r, pt + pr @ t
        parents.append(-1 if parent is None else names.index(parent))
    return names, parents, np.array([pos[n] for n in names]).reshape(-1, 3)


class VmcSkeletons:
    """Kinect-20 skeletons from a stream of VMC messages (one performer).

    Per UDP datagram: `start_packet(bundle)`, `message(address, args)` for each OSC message in it, then
    `end_of_packet(bundle)`; `message` and `end_of_packet` return a Skeleton when a frame completes.
    `blendshapes` is the face applied so far ((52,) in `BLENDSHAPES` order), or None before any.
    """

    def __init__(self):
        self.bones: dict = {}
        self.clips: dict = {}            # /VMC/Ext/Blend/Val since the last Apply
        self.applied: dict = {}          # every clip's weight as of the last Apply
        self.blendshapes: np.ndarray | None = None
        self.root = None
        self.moved = False
        self.frames = 0
        self._in_bundle = False
        self._map_key = None
        self._map = None

    def message(self, address: str, args) -> Skeleton | None:
        if address == "/VMC/Ext/Bone/Pos" and len(args) >= 8 and isinstance(args[0], str):
            values = _numbers(args[1:8])
            if values is not None and args[0] in UNITY_PARENTS:
                self.bones[args[0]] = (values[:3], values[3:])
                self.moved = True
        elif address == "/VMC/Ext/Root/Pos" and len(args) >= 8:
            values = _numbers(args[1:8])
            if values is not None:
                self.root = (values[:3], values[3:])
        elif address == "/VMC/Ext/Blend/Val" and len(args) >= 2 and isinstance(args[0], str):
            value = _numbers(args[1:2])
            if value is not None:
                self.clips[args[0]] = float(value[0])
        if address == "/VMC/Ext/Blend/Apply" and self.clips:
            self.applied.update(self.clips)  # a clip keeps its weight until it is sent again
            self.clips = {}
            self.blendshapes = blendshapes_from_clips(self.applied, BLENDSHAPES)
        if address in ("/VMC/Ext/T", "/VMC/Ext/Blend/Apply") and not self._in_bundle:
            return self._frame()
        return None

    def start_packet(self, bundle: bool) -> None:
        self._in_bundle = bundle

    def end_of_packet(self, bundle: bool) -> Skeleton | None:
        self._in_bundle = False
        return self._frame() if bundle else None

    def _frame(self) -> Skeleton | None:
        if not self.moved or "Hips" not in self.bones:
            return None
        self.moved = False
        names, parents, positions = world_positions(self.bones, self.root)
        key = (names, tuple(parents))
        if key != self._map_key:
            self._map_key = key
            self._map = map_humanoid(names, parents, positions, vrm={vrm_name(n): i for i, n in enumerate(names)})
        joints, tracked = kinect_frames(self._map, positions)
        self.frames += 1
        return Skeleton(KINECT20, joints, tracked)


def _numbers(values) -> np.ndarray | None:
    try:
        out = np.array([float(v) for v in values])
    except (TypeError, ValueError):
        return None
    return out if np.isfinite(out).all() else None


def listen_address(text: str) -> tuple[str, int]:
    """`--vmc-listen PORT` or `HOST:PORT` -> (host, port); the host defaults to 127.0.0.1 (this machine only)."""
    from .send import parse_address
    if text.strip().isdigit():
        text = ":" + text.strip()
    return parse_address(text, "--vmc-listen")


def check_listen(host: str, port: int) -> None:
    """Raise KinetreError now when UDP `host:port` cannot be listened on (in use, not this machine's)."""
    import socket

    from ..errors import KinetreError
    try:
        family = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0][0]
        with socket.socket(family, socket.SOCK_DGRAM) as probe:
            probe.bind((host, port))
    except OSError as e:
        raise KinetreError(f"--vmc-listen {host}:{port}: cannot listen there ({e.strerror or e})") from None


class VmcListener:
    """A python-osc UDP server that turns each performer's packets into skeletons.

    `on_skeleton(address, skeleton, blendshapes)` is called in the event loop for every completed frame,
    `address` the performer's (host, port), `blendshapes` its face ((52,) or None, `VmcSkeletons.blendshapes`);
    performers are told apart by that address.
    """

    def __init__(self, on_skeleton, host: str = "127.0.0.1", port: int = 39539):
        self.on_skeleton = on_skeleton
        self.address = (host, port)
        self.performers: dict = {}
        self.packets = 0
        self.transport = None

    async def start(self) -> None:
        import asyncio

        from pythonosc.dispatcher import Dispatcher
        from pythonosc.osc_server import AsyncIOOSCUDPServer

        listener = self

        class PerPacket(Dispatcher):
            """python-osc hands each datagram to its dispatcher; this one keeps the datagram's boundary."""

            def call_handlers_for_packet(self, data, client_address):
                listener.packet(data, client_address)
                return []

        server = AsyncIOOSCUDPServer(self.address, PerPacket(), asyncio.get_running_loop())
        try:
            self.transport, _ = await server.create_serve_endpoint()
        except OSError as e:
            from ..errors import KinetreError
            raise KinetreError(f"--vmc-listen {self.address[0]}:{self.address[1]}: cannot listen there "
                               f"({e.strerror or e})") from None

    @property
    def port(self) -> int:
        """The port actually bound (port 0 asks the system for a free one)."""
        return self.transport.get_extra_info("sockname")[1] if self.transport else self.address[1]

    def packet(self, data: bytes, address) -> None:
        from pythonosc.osc_bundle import OscBundle
        from pythonosc.osc_packet import OscPacket, ParseError
        try:
            messages = OscPacket(data).messages
        except ParseError:
            return                                    # not OSC: ignored, as a VMC receiver does
        self.packets += 1
        performer = self.performers.setdefault(address, VmcSkeletons())
        bundle = OscBundle.dgram_is_bundle(data)
        performer.start_packet(bundle)
        for m in messages:
            done = performer.message(m.message.address, m.message.params)
            if done is not None:
                self.on_skeleton(address, done, performer.blendshapes)
        done = performer.end_of_packet(bundle)
        if done is not None:
            self.on_skeleton(address, done, performer.blendshapes)

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()
            self.transport = None
