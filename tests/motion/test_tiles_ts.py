"""The page's square search (web/src/capture/tiles.ts, run under node) is `kinetre capture`'s: the same
squares for any image size and overlap, the same landmarks back in the whole image, the same detections
kept when people are found twice."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kinetre.motion.tiles import Tile, distinct, square_tiles
from web_bundle import bundled, run_node

RUNNER = Path(__file__).resolve().parent / "node" / "tiles_ts.mjs"


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    return bundled(tmp_path_factory.mktemp("ts"), "capture/tiles.ts")


def people(rng, count: int, landmarks: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Detections of `count` people (pixels), most found again a few pixels off, some with a few landmarks
    cut off by a square's edge and guessed far away; people may stand close together."""
    points, scores = [], []
    for _ in range(count):
        centre, size = rng.uniform(50, 600, 2), rng.uniform(20, 200)
        body = centre + rng.normal(scale=size / 3, size=(landmarks, 2))
        for _ in range(rng.integers(1, 4)):
            again = body + rng.normal(scale=rng.choice([0.01, 0.1, 0.4]) * size, size=body.shape)
            cut = rng.choice(landmarks, size=rng.integers(0, landmarks // 4 + 1), replace=False)
            again[cut] += rng.uniform(-size, size, (len(cut), 2))
            points.append(again)
            scores.append(round(float(rng.uniform()), 1))  # ties happen: the given order breaks them
    return points, np.array(scores)


def test_the_page_searches_the_same_squares_maps_back_and_merges_like_capture(bundle):
    rng = np.random.default_rng(7)
    sizes = [(640, 360, 1 / 3), (320, 240, 1 / 3), (360, 640, 1 / 3), (576, 576, 1 / 3), (1920, 1080, 1 / 3),
             (1280, 720, 0.5), (3000, 400, 0.2), (421, 350, 1 / 3)]
    sizes += [(int(w), int(h), float(o)) for w, h, o in zip(rng.integers(16, 4000, 300), rng.integers(16, 4000, 300),
                                                             rng.uniform(0.1, 0.6, 300))]
    starts = [(k - 1) * (max(w, h) - min(w, h)) / (len(square_tiles(w, h, o)) - 2)
              for w, h, o in sizes for k in range(2, len(square_tiles(w, h, o)))]
    assert any(abs(s % 1 - 0.5) < 1e-9 for s in starts)  # numpy's halves-to-even rounding is exercised
    maps = []
    for _ in range(20):
        w, h = (int(v) for v in rng.integers(100, 2000, 2))
        tile = square_tiles(w, h)[int(rng.integers(0, len(square_tiles(w, h))))]
        maps.append({"tile": [tile.x, tile.y, tile.width, tile.height], "marks": rng.uniform(-0.2, 1.2, (33, 3)).tolist(),
                     "width": w, "height": h})
    crowds = [people(rng, int(rng.integers(1, 5)), n) for n in (33, 21, 32, 33, 33, 478)]
    page = run_node(RUNNER, bundle, {"tiles": sizes, "toImage": maps,
                        "distinct": [{"points": [p.tolist() for p in ps], "scores": s.tolist()} for ps, s in crowds]})

    assert page["tiles"] == [[[t.x, t.y, t.width, t.height] for t in square_tiles(w, h, o)] for w, h, o in sizes]
    for m, got in zip(maps, page["toImage"]):
        tile, marks = Tile(*m["tile"]), np.array(m["marks"])
        np.testing.assert_allclose(np.array(got)[:, :2], tile.to_image(marks[:, :2], m["width"], m["height"]),
                                   atol=1e-12)
        np.testing.assert_allclose(np.array(got)[:, 2], marks[:, 2] * tile.width / m["width"], atol=1e-12)
    expected = [distinct(ps, s) for ps, s in crowds]
    assert page["distinct"] == expected
    # the crowds mix people found once, found again and close neighbours: the merge does drop and keep
    assert sum(len(ps) - len(k) for (ps, _), k in zip(crowds, expected)) >= 5
    assert all(len(k) >= 1 for k in expected)
