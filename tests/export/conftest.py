"""Fixtures for the export tests (helpers live in takes.py)."""
from __future__ import annotations

import pytest
from export.takes import capsule


@pytest.fixture
def capsule_take():
    """(mesh, graph, poses, fps): a UV-mapped capsule along z with a 12-frame bend, 40 nodes."""
    return capsule()
