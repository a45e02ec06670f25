"""Square tiles of a wide image and merging detections found in several of them."""
from __future__ import annotations

import numpy as np

from kinetre.motion.tiles import Tile, distinct, square_tiles


def test_tiles_cover_a_wide_frame_with_overlapping_squares():
    tiles = square_tiles(640, 360)
    assert tiles[0] == Tile(0, 0, 640, 360)
    squares = tiles[1:]
    assert all(t.width == t.height == 360 and t.y == 0 for t in squares)
    assert squares[0].x == 0 and squares[-1].x + 360 == 640
    for a, b in zip(squares, squares[1:]):
        assert a.x + a.width - b.x >= 360 / 3            # neighbours share at least a third
    # any span narrower than a third of a square lies whole inside one square
    for start in range(0, 640 - 120):
        assert any(t.x <= start and start + 120 <= t.x + t.width for t in squares)


def test_a_tall_frame_is_tiled_down_and_a_square_one_not_at_all():
    tall = square_tiles(480, 1280)
    assert all(t.width == t.height == 480 and t.x == 0 for t in tall[1:]) and tall[-1].y + 480 == 1280
    assert square_tiles(576, 576) == (Tile(0, 0, 576, 576),)


def test_tile_coordinates_map_back_to_the_whole_image():
    t = Tile(140, 0, 360, 360)
    np.testing.assert_allclose(t.to_image(np.array([[0.0, 0.0], [1.0, 0.5]]), 640, 360),
                               [[140 / 640, 0.0], [500 / 640, 0.5]])


def test_the_same_person_from_two_tiles_is_kept_once_and_neighbours_stay_apart():
    rng = np.random.default_rng(1)
    body = rng.uniform(0, 100, size=(33, 2))
    again = body + rng.normal(scale=2.0, size=body.shape)
    again[:5] += 60.0                                      # a few landmarks a tile's edge cut off and guessed
    neighbour = body + np.array([70.0, 0.0])               # someone standing close by
    kept = distinct([body, again, neighbour], np.array([0.7, 0.9, 0.5]))
    assert kept == [1, 2]                                  # the better-scored copy, and the neighbour
    assert distinct([], np.zeros(0)) == []
