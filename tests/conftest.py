"""Shared fixtures: the real test data beside the repository, and small synthetic meshes/skeletons."""
from __future__ import annotations

from pathlib import Path

import pytest

import kinetre
from synthetic import body_mesh

DATA = (Path(__file__).resolve().parents[1] / ".." / "shared" / "data").resolve()


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
