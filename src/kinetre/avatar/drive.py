"""A take's hands and face on an avatar, after its body (Algorithm 1, `retarget.retarget`): the main
person's hand landmarks turn the finger bones (`retarget.retarget_fingers` over `fingers.map_fingers`),
their face blendshapes weigh the morph targets (`expressions.map_expressions`)."""
from __future__ import annotations

import numpy as np

from .expressions import map_expressions
from .fingers import map_fingers
from .retarget import retarget_fingers


def hands_and_face(avatar, bonemap, plan, motion, take, say=lambda *a: None):
    """The take's hands on the avatar's finger bones and its face blendshapes on the avatar's expressions:
    (motion with the fingers, mesh index -> (T, targets) morph weights or None)."""
    hands, faces, morphs = take.main_hands(), take.main_blendshapes(), None
    if hands is not None:
        fingers = map_fingers(avatar, bonemap)
        if fingers:
            motion = retarget_fingers(avatar, plan, fingers, motion, hands)
            seen = np.isfinite(hands).all(axis=(2, 3)).any(axis=1).mean()
            say(f"fingers: {len(fingers.chains)} finger chains follow the hands (seen in {seen:.0%} of frames)")
        else:
            say("fingers: the take has hands, the avatar no finger joints")
    if faces is not None:
        expressions = map_expressions(avatar, take.blendshape_names)
        if expressions:
            morphs = expressions.weights(faces)
            say(f"face: blendshapes drive {sum(m.shape[1] for m in morphs.values())} morph targets "
                f"({'VRM expressions' if expressions.how == 'vrm' else 'ARKit names'})")
        else:
            say("face: the take has blendshapes, the avatar no matching morph targets or VRM expressions")
    return motion, morphs
