"""The Examples blocks in the motion modules' docstrings run and hold."""
from __future__ import annotations

import doctest

import pytest

import kinetre.motion.bvh
import kinetre.motion.filters
import kinetre.motion.gltf
import kinetre.motion.people
import kinetre.motion.source
import kinetre.motion.stream
import kinetre.motion.take
import kinetre.motion.tiles


@pytest.mark.parametrize("module", [kinetre.motion.bvh, kinetre.motion.filters, kinetre.motion.gltf,
                                    kinetre.motion.people, kinetre.motion.source, kinetre.motion.stream,
                                    kinetre.motion.take, kinetre.motion.tiles])
def test_docstring_examples(module):
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
