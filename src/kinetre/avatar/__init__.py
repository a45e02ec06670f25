"""Rigged humanoid avatars driven by their own bones (avateering paper §3, Algorithm 1).

load.py (glTF/GLB/VRM in, `Avatar` out) → bonemap.py (avatar joints ↔ Kinect-20, by VRM, names, geometry)
→ retarget.py (tracked joints → the avatar's joint rotations, per frame) → skin.py (the avatar's own LBS)
→ export.py (animated GLB, BVH, video).
"""
