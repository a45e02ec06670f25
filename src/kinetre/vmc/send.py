"""An avatar's retargeted frames as VMC protocol messages (OSC over UDP), in Unity's humanoid terms.

Per frame, in this order: `/VMC/Ext/OK` (loaded, calibrated, tracking), `/VMC/Ext/T` (seconds),
`/VMC/Ext/Root/Pos`, one `/VMC/Ext/Bone/Pos` per humanoid bone (Unity HumanBodyBones names), optional
`/VMC/Ext/Blend/Val` per blendshape, then `/VMC/Ext/Blend/Apply`; each frame is one OSC bundle.

Rotations. A VMC receiver applies each bone's *local* rotation to its own normalised humanoid, whose rest is
the T-pose with every rotation identity. So for each sent bone b the world rotation relative to the T-pose is

    R_T(b) = R(b) · C(b),

R(b) the retargeted world rotation relative to the avatar's bind pose (`AvatarMotion.rotations`) and C(b) the
smallest rotation taking b's T-pose direction (legs down, spine up, arms out sideways) to its bind direction
(an A-posed avatar has C ≠ I at the arms; bones without a defined direction, hands, feet, head, take their
parent's). The local rotation sent is R_T(parent)ᵀ · R_T(b), parent being the nearest sent ancestor in Unity's
humanoid hierarchy, so a receiver that leaves the bones in between at rest reproduces every world rotation.

Axes. Everything is first turned about +Y so the avatar faces +Z (its left on +X, glTF/VRM 1.0 style), then
mirrored into Unity's left-handed frame (facing +Z, left on −X): positions (x, y, z) → (−x, y, z), unit
quaternions (x, y, z, w) → (x, −y, −z, w) (the mirror M = diag(−1, 1, 1) maps R to M R M).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..avatar.bonemap import BoneMap
from ..avatar.retarget import AvatarMotion, RetargetPlan
from ..errors import KinetreError

PORT = 39539  # the VMC performer's default ("Marionette") port

# Unity HumanBodyBones name -> (Kinect-20 joint playing it, nearest sent parent, T-pose direction or None)
BONES = {
    "Hips": ("HipCenter", None, None),
    "Spine": ("Spine", "Hips", (0.0, 1.0, 0.0)),
    "Neck": ("ShoulderCenter", "Spine", (0.0, 1.0, 0.0)),
    "Head": ("Head", "Neck", None),
    "LeftUpperArm": ("ShoulderLeft", "Spine", (1.0, 0.0, 0.0)),
    "LeftLowerArm": ("ElbowLeft", "LeftUpperArm", (1.0, 0.0, 0.0)),
    "LeftHand": ("WristLeft", "LeftLowerArm", None),
    "RightUpperArm": ("ShoulderRight", "Spine", (-1.0, 0.0, 0.0)),
    "RightLowerArm": ("ElbowRight", "RightUpperArm", (-1.0, 0.0, 0.0)),
    "RightHand": ("WristRight", "RightLowerArm", None),
    "LeftUpperLeg": ("HipLeft", "Hips", (0.0, -1.0, 0.0)),
    "LeftLowerLeg": ("KneeLeft", "LeftUpperLeg", (0.0, -1.0, 0.0)),
    "LeftFoot": ("AnkleLeft", "LeftLowerLeg", None),
    "LeftToes": ("FootLeft", "LeftFoot", None),
    "RightUpperLeg": ("HipRight", "Hips", (0.0, -1.0, 0.0)),
    "RightLowerLeg": ("KneeRight", "RightUpperLeg", (0.0, -1.0, 0.0)),
    "RightFoot": ("AnkleRight", "RightLowerLeg", None),
    "RightToes": ("FootRight", "RightFoot", None),
}
MIRROR = np.diag([-1.0, 1.0, 1.0])


@dataclass(frozen=True, eq=False)
class VmcFrames:
    """Retargeted frames in VMC's terms (Unity axes, metres as the avatar's units).

    Attributes
    ----------
    bones : tuple of str, (B,)
        Unity HumanBodyBones names, parents before children.
    positions : (T, B, 3) float64
        Local position of each bone (the hips': relative to the root, which stays at the origin).
    rotations : (T, B, 4) float64
        Local rotation as a unit quaternion (x, y, z, w), Unity's left-handed axes.
    """

    bones: tuple
    positions: np.ndarray
    rotations: np.ndarray

    def __len__(self) -> int:
        return int(self.positions.shape[0])


def vmc_frames(plan: RetargetPlan, bonemap: BoneMap, motion: AvatarMotion) -> VmcFrames:
    """The module docstring's local rotations and positions for every frame of `motion`."""
    a = plan.align                                       # Kinetre facing (+Z) -> the avatar's
    names = tuple(b for b, (kj, _, _) in BONES.items() if kj in bonemap.joints)
    joint = {b: bonemap.joints[BONES[b][0]] for b in names}
    rest, correction = {}, {}
    for b in names:
        kj, parent, tpose = BONES[b]
        j = joint[b]
        if tpose is not None and plan.aim_from[j] >= 0:
            correction[b] = _min_rotation(np.array(tpose), a.T @ plan.rest_aim[j])
        else:
            correction[b] = correction.get(parent, np.eye(3)) if parent else np.eye(3)
        above = plan.bind_positions[joint[parent]] if parent else np.zeros(3)
        rest[b] = a.T @ (plan.bind_positions[j] - above)
    t = len(motion)
    world = {b: a.T @ motion.rotations[:, joint[b]] @ a @ correction[b] for b in names}   # R_T, facing +Z
    positions = np.zeros((t, len(names), 3))
    rotations = np.zeros((t, len(names), 4))
    for k, b in enumerate(names):
        parent = BONES[b][1]
        local = world[b] if parent is None else np.swapaxes(world[parent], 1, 2) @ world[b]
        rotations[:, k] = _unity_quaternion(local)
        positions[:, k] = rest[b] @ MIRROR
        if parent is None:
            positions[:, k] = (motion.positions[:, joint[b]] @ a) @ MIRROR
    return VmcFrames(names, positions, rotations)


def unity_from_gltf_quaternion(q: np.ndarray) -> np.ndarray:
    """(…, 4) (x, y, z, w) in a right-handed +Y up frame -> Unity's, mirrored in x: (x, −y, −z, w)."""
    q = np.asarray(q, dtype=np.float64)
    return q * np.array([1.0, -1.0, -1.0, 1.0])


def frame_bundle(frames: VmcFrames, k: int, seconds: float, blend: dict | None = None) -> bytes:
    """Frame `k` as one OSC bundle: OK, T, Root/Pos, Bone/Pos…, Blend/Val…, Blend/Apply."""
    from pythonosc.osc_bundle_builder import IMMEDIATELY, OscBundleBuilder
    from pythonosc.osc_message_builder import OscMessageBuilder

    bundle = OscBundleBuilder(IMMEDIATELY)

    def add(address, *values):
        m = OscMessageBuilder(address)
        for v in values:
            m.add_arg(v)
        bundle.add_content(m.build())

    add("/VMC/Ext/OK", 1, 3, 0, 1)                    # loaded, calibrated, normal mode, tracking
    add("/VMC/Ext/T", float(seconds))
    add("/VMC/Ext/Root/Pos", "root", 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    for i, name in enumerate(frames.bones):
        add("/VMC/Ext/Bone/Pos", name, *(float(v) for v in frames.positions[k, i]),
            *(float(v) for v in frames.rotations[k, i]))
    for name, value in (blend or {}).items():
        add("/VMC/Ext/Blend/Val", str(name), float(value))
    add("/VMC/Ext/Blend/Apply")
    return bundle.build().dgram


def parse_address(text: str) -> tuple[str, int]:
    """"HOST:PORT", "HOST" or ":PORT" -> (host, port); the defaults are 127.0.0.1 and 39539."""
    host, _, port = text.rpartition(":") if ":" in text else (text, "", "")
    try:
        number = int(port) if port else PORT
    except ValueError:
        raise KinetreError(f"--vmc {text}: the port must be a number (HOST:PORT)") from None
    if not 0 < number < 65536:
        raise KinetreError(f"--vmc {text}: the port must be 1..65535")
    return host or "127.0.0.1", number


class VmcSender:
    """A UDP socket that sends VMC bundles to one performer's receiver."""

    def __init__(self, host: str = "127.0.0.1", port: int = PORT):
        import socket
        self.address = (host, port)
        try:
            self.sock = socket.socket(socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0][0],
                                      socket.SOCK_DGRAM)
        except OSError as e:
            raise KinetreError(f"--vmc {host}:{port}: cannot reach that address ({e})") from None
        self.sent = 0

    def send(self, dgram: bytes) -> None:
        try:
            self.sock.sendto(dgram, self.address)
        except OSError:
            return  # a receiver that is not up yet (ICMP refused) must not stop the stream
        self.sent += 1

    def stream(self, frames: VmcFrames, fps: float, blend: list | None = None, clock=time.monotonic,
               sleep=time.sleep) -> int:
        """Send every frame at its time (frame k at start + k / fps); returns the frames sent."""
        start = clock()
        for k in range(len(frames)):
            due = start + k / fps
            wait = due - clock()
            if wait > 0:
                sleep(wait)
            self.send(frame_bundle(frames, k, k / fps, blend[k] if blend else None))
        return len(frames)

    def close(self) -> None:
        self.sock.close()


def _min_rotation(u, v) -> np.ndarray:
    """Smallest rotation taking direction u onto v (Rodrigues)."""
    u = u / np.linalg.norm(u)
    v = v / np.linalg.norm(v)
    axis, c = np.cross(u, v), float(u @ v)
    s2 = float(axis @ axis)
    if s2 < 1e-24:
        if c > 0:
            return np.eye(3)
        perp = np.cross(u, [1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.cross(u, [0.0, 1.0, 0.0])
        perp /= np.linalg.norm(perp)
        return 2.0 * np.outer(perp, perp) - np.eye(3)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + k + ((1.0 - c) / s2) * (k @ k)


def _unity_quaternion(r: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotations (right-handed, avatar facing +Z) -> (T, 4) Unity quaternions (x, y, z, w)."""
    from scipy.spatial.transform import Rotation
    return unity_from_gltf_quaternion(Rotation.from_matrix(r).as_quat())
