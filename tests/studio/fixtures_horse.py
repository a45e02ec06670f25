"""A synthetic horse costume for two people (the paper's demo): a body on four legs, 1.6 m tall, whose leg
pairs stand 0.9 m apart, where the example joint map (examples/maps/two-people-horse.json) puts each
person's legs, and as far apart across as a person's legs."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh


def horse_obj(target: Path) -> Path:
    parts = [trimesh.creation.box(extents=(0.5, 0.45, 1.6), transform=trimesh.transformations.translation_matrix(
        (0, 1.0, 0)))]  # the body, nose to tail along z
    for x in (-0.1, 0.1):
        for z in (-0.45, 0.45):
            parts.append(trimesh.creation.box(extents=(0.14, 0.85, 0.16),
                                              transform=trimesh.transformations.translation_matrix((x, 0.425, z))))
    parts.append(trimesh.creation.box(extents=(0.25, 0.45, 0.3),
                                      transform=trimesh.transformations.translation_matrix((0, 1.375, 0.75))))
    horse = trimesh.util.concatenate([p.subdivide().subdivide() for p in parts])
    assert np.isclose(horse.bounds[1][1] - horse.bounds[0][1], 1.6)
    horse.export(target)
    return target
