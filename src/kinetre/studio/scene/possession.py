"""Possession: a user's pose bound to a mesh, and the rig its possessors drive.

A user possesses a mesh with its body (optionally a subset of joints, or the joints a joint map gives the
n-th person), or with one hand put inside the mesh (a hand puppet, fitted from the shapes). Every change of
who possesses a mesh attaches its rig anew from all its possessors' binding poses at once.
"""
from __future__ import annotations

import asyncio
from typing import Callable

from ...deform.pose import GraphPose
from ...errors import AttachError
from ...motion.hands import fit_puppet
from ...skeleton.models import HAND21, Skeleton
from ...skeleton.rig import BONE_RADIUS, REACH
from ...skeleton.subsets import subset_mask
from ..channels import now_ms
from ..protocol import check_hand
from .meshes import Meshes, SceneMesh, stand_in
from .solve_loop import Publisher
from .users import User, Users, arrival


class Possession:
    """Who possesses which of the scene's meshes, and each mesh's rig."""

    def __init__(self, users: Users, meshes: Meshes, publisher: Publisher, wake: Callable[[SceneMesh], None]):
        """`wake(m)`: mesh `m`'s rig changed, its next solve may start."""
        self.users, self.meshes, self.publisher, self.wake = users, meshes, publisher, wake

    async def possess(self, user: User, m: SceneMesh, subset=None, hand: str | None = None,
                      joint_map=None) -> None:
        """Bind the user's current pose to mesh `m`, or with `hand` ("left", "right") that hand's, fitted into
        the mesh from the shapes (a hand puppet), letting go of any other mesh it possessed; raises
        AttachError when nothing is near the mesh or the hand is not seen. With a `joint_map` and no
        `subset`, the n-th user to possess the mesh drives with the joints its n-th source keeps, moved to
        where that source stands."""
        if hand is not None:
            check_hand(hand)
            await arrival(lambda: user.seen_hand(hand) is not None)
            await self._possess_by_hand(user, m, subset, hand)
            return
        await arrival(lambda: user.tracking)
        if not user.tracking:
            raise AttachError("no tracked skeleton from this client yet: nothing to possess with")
        source = None
        if subset is None and joint_map is not None:
            others = sum(1 for c in self.users.possessing(m.id) if c != user.client)
            if others < len(joint_map.sources):
                source = joint_map.sources[others]
                subset = source.joint_names(user.latest.model, joint_map.path)
        if subset is not None:
            subset_mask(user.latest.model, subset)  # BadSkeletonError on an unknown name
        stand = stand_in(user.latest, source, m.placement) if source is not None else None
        await self._bind(user, m, subset, None, None, stand)

    async def _possess_by_hand(self, user: User, m: SceneMesh, subset, hand: str) -> None:
        marks = user.seen_hand(hand)
        if marks is None:
            raise AttachError(f"no {hand} hand tracked from this client yet: show it to the camera")
        if subset is not None:
            subset_mask(HAND21, subset)  # BadSkeletonError on a name that is no part of a hand
        frame = Skeleton.from_positions(HAND21, marks)
        # the shape fit searches for a second or so: off the event loop
        fitted = await asyncio.to_thread(fit_puppet, frame, m.mesh, m.graph.nodes)
        await self._bind(user, m, subset, hand, fitted, None)

    async def _bind(self, user: User, m: SceneMesh, subset, hand: str | None, puppet, stand) -> None:
        """Possess mesh `m` with the user's newest frame, driven as given; back to what it was when attaching
        fails. A mesh the user possessed before lets go of it."""
        before = self.meshes.get(user.mesh) if user.bind is not None else None
        old = user.bind, user.subset, user.stand, user.hand, user.puppet, user.mesh
        user.subset, user.stand, user.hand, user.puppet = subset, stand, hand, puppet
        user.bind = user.driving(m.placement)
        user.mesh = m.id
        try:
            await self.rebuild(m)
        except Exception:
            user.bind, user.subset, user.stand, user.hand, user.puppet, user.mesh = old
            await self.rebuild(m)
            raise
        if before is not None and before is not m:
            await self.rebuild(before)

    async def release(self, user: User) -> None:
        """The user lets go of the mesh it possesses."""
        m = self.meshes.get(user.mesh)
        user.let_go()
        if m is not None:
            await self.rebuild(m)

    def release_all(self, m: SceneMesh) -> None:
        """Every possessor of mesh `m` lets go (the mesh leaves the scene)."""
        for user in self.users.values():
            if user.mesh == m.id:
                user.let_go()
        m.rig, m.possessors = None, []

    def rebuild_later(self, m: SceneMesh) -> None:
        asyncio.get_running_loop().create_task(self.rebuild(m))

    async def rebuild(self, m: SceneMesh) -> None:
        """Attach mesh `m`'s rig from all its possessors' binding poses; with none, the mesh goes back to
        rest."""
        async with m.lock:
            await m.idle()  # the solve in flight ends with the rig it was sent to
            if not self.meshes.holds(m):
                return  # replaced or removed meanwhile
            possessors = self.users.possessing(m.id)
            if not possessors:
                m.rig, m.possessors = None, []
                m.pose = GraphPose.identity(m.graph.node_count)  # let go: back to rest
                self.publisher.publish(m, now_ms())
                return
            users = [self.users[c] for c in possessors]
            binds = [u.bind for u in users]
            # a hand puppet reaches as far as its fit scaled it up (people: the attachment's own reach)
            reach = {} if all(u.puppet is None for u in users) else {
                "reach": [REACH * (1.0 if u.puppet is None else u.puppet.metre) for u in users],
                "bone_radius": [BONE_RADIUS * (1.0 if u.puppet is None else u.puppet.metre) for u in users]}
            m.attached = await m.solver.attach(m.graph, binds if len(binds) > 1 else binds[0], **reach)
            m.rig = m.solver
            m.possessors = possessors
        m.dirty.set()
        self.wake(m)
