"""Shared fixtures: the real test data beside the repository, and small synthetic meshes/skeletons."""
from __future__ import annotations

from pathlib import Path

import pytest

import kinetre
from synthetic import body_mesh

DATA = (Path(__file__).resolve().parents[1] / ".." / "shared" / "data").resolve()

# The quick tier (`make check`: pytest -m "not slow") is the unit and numeric tests (docs/testing.md). A test is
# `slow` when it needs a running service (a browser in tests/e2e, a studio server process, NATS, Blender,
# ffmpeg, the command line in a subprocess) or heavy numeric work (large real meshes and rigs, scans, video
# tracking, whole-walk solver agreement). A test using one of these fixtures (each starts a service) is slow;
# any other is marked `slow` itself (`pytestmark = pytest.mark.slow` for a whole module).
SERVICE_FIXTURES = frozenset({"studio", "studio_page", "loaded_studio", "creature_studio", "horse_studio",
                              "fresh_studio", "vmc_studio", "nats", "network", "rooms", "probed"})


def pytest_collection_modifyitems(config, items):
    e2e = Path(__file__).resolve().parent / "e2e"
    for item in items:
        if e2e in Path(item.fspath).resolve().parents or SERVICE_FIXTURES & set(item.fixturenames):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def data_dir() -> Path:
    assert DATA.is_dir(), f"test data missing: expected {DATA} (../shared/data beside the repository)"
    return DATA


@pytest.fixture(scope="session")
def body():
    return body_mesh()


@pytest.fixture(scope="session")
def body_graph(body):
    return kinetre.build_graph(body, nodes=128, seed=0)
