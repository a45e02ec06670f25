"""An avatar's retargeted frames as VMC protocol messages (OSC over UDP), in Unity's humanoid terms.

Per frame, in this order: `/VMC/Ext/OK` (loaded, calibrated, tracking), `/VMC/Ext/T` (seconds),
`/VMC/Ext/Root/Pos`, one `/VMC/Ext/Bone/Pos` per humanoid bone (Unity HumanBodyBones names, the finger bones
when the hands are tracked), optional `/VMC/Ext/Blend/Val` per blendshape, then `/VMC/Ext/Blend/Apply`; each
frame is one OSC bundle.

Rotations are the normalised humanoid's (avatar/normalized.py): local to the nearest sent parent and
relative to the T-pose, which is a VMC receiver's rest. Positions: the T-pose offsets from that parent (so
composing them down the hierarchy with the rotations gives the posed joints), the hips' their place above
the floor.

Face. `/VMC/Ext/Blend/Val` names are a receiver's blendshape clips: VRM 0.x's preset names (A, I, U, E, O,
Blink, Blink_L, Blink_R, Joy, Angry, Sorrow, Fun, LookUp...; `BLEND_NAMES`) for the VRM 1.0 expressions a
face's ARKit weights make (avatar/expressions.py), and every ARKit name as it is (jawOpen, eyeBlinkLeft...),
as face trackers (iFacialMocap, XR Animator) send them to "perfect sync" avatars, which have a clip for each.

Axes. The normalised humanoid faces +Z with its left on +X (glTF/VRM 1.0 style); Unity's left-handed frame
faces +Z with the left on −X: positions (x, y, z) → (−x, y, z), unit quaternions (x, y, z, w) → (x, −y, −z, w)
(the mirror M = diag(−1, 1, 1) maps R to M R M).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..avatar.bonemap import BoneMap
from ..avatar.expressions import held_weights, vrm_expressions
from ..avatar.fingers import FingerMap
from ..avatar.normalized import BONES, PARENTS, NormalizedMotion, normalized_motion
from ..avatar.retarget import AvatarMotion, RetargetPlan
from ..errors import KinetreError
from ..rotation import matrix_quaternions

__all__ = ["BLEND_NAMES", "BONES", "MIRROR", "PARENTS", "PORT", "VmcFrames", "VmcSender", "blend_frames",
           "frame_bundle", "parse_address", "unity_frames", "vmc_frames"]

PORT = 39539
# VRM 1.0 expression -> the VRM 0.x blendshape clip name VMC receivers (VSeeFace, Warudo) know it by
BLEND_NAMES = {"aa": "A", "ih": "I", "ou": "U", "ee": "E", "oh": "O", "blink": "Blink", "blinkLeft": "Blink_L",
               "blinkRight": "Blink_R", "happy": "Joy", "angry": "Angry", "sad": "Sorrow", "relaxed": "Fun",
               "surprised": "Surprised", "lookUp": "LookUp", "lookDown": "LookDown", "lookLeft": "LookLeft",
               "lookRight": "LookRight"}  # the VMC performer's default ("Marionette") port

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


def vmc_frames(plan: RetargetPlan, bonemap: BoneMap, motion: AvatarMotion,
               fingers: FingerMap | None = None) -> VmcFrames:
    """Every frame of `motion` on the normalised humanoid, mirrored into Unity's axes; with `fingers`, the
    finger bones of its chains too."""
    return unity_frames(normalized_motion(plan, bonemap, motion, fingers))


def unity_frames(norm: NormalizedMotion) -> VmcFrames:
    """A normalised humanoid's frames in Unity's left-handed axes (the module docstring)."""
    t = len(norm)
    positions = np.repeat((norm.rest @ MIRROR)[None], t, axis=0)
    positions[:, 0] = norm.hips @ MIRROR
    rotations = _unity_quaternion(norm.rotations.reshape(-1, 3, 3)).reshape(t, len(norm.bones), 4)
    return VmcFrames(norm.bones, positions, rotations)


def blend_frames(names, blendshapes: np.ndarray) -> list[dict]:
    """(T, B) blendshape weights named `names` -> per frame {VMC blendshape name: weight}: the VRM 0.x presets
    they make, then every ARKit name (a frame without a face holds the last one's, as `vrm_expressions`)."""
    preset, _ = vrm_expressions(names, blendshapes)
    held = np.clip(held_weights(blendshapes), 0.0, 1.0)
    named = {BLEND_NAMES.get(k, k): w for k, w in preset.items()} | \
        {n: held[:, i] for i, n in enumerate(names) if not n.startswith("_")}
    t = len(next(iter(named.values()))) if named else 0
    return [{name: float(w[k]) for name, w in named.items()} for k in range(t)]


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


def parse_address(text: str, option: str = "--vmc") -> tuple[str, int]:
    """"HOST:PORT", "HOST" or ":PORT" -> (host, port); the defaults are 127.0.0.1 and 39539."""
    host, _, port = text.rpartition(":") if ":" in text else (text, "", "")
    try:
        number = int(port) if port else PORT
    except ValueError:
        raise KinetreError(f"{option} {text}: the port must be a number (HOST:PORT)") from None
    if not 0 < number < 65536:
        raise KinetreError(f"{option} {text}: the port must be 1..65535")
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


def _unity_quaternion(r: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotations (right-handed, avatar facing +Z) -> (T, 4) Unity quaternions (x, y, z, w)."""
    return unity_from_gltf_quaternion(matrix_quaternions(r))
