"""Fuzzing every file reader with structure-aware mutations of small valid files (hypothesis, fixed seed).

Each mutated file runs in a separate reader process (harness.py) through what a user's command or the studio
does with it (`kinetre info`, the glTF motion and avatar readers, a studio upload's graph, a scan). Every case
must end in an answer: read, or refused with a KinetreError of one line naming the file. A traceback, a native
crash (segmentation fault) or a hang fails the case, and hypothesis shrinks it to a small reproducer.

KINETRE_FUZZ_EXAMPLES sets the cases per reader (the quick run in `make test` uses the default; `make fuzz`
runs many more with fresh randomness). Files it finds that once broke a reader are kept in cases/ and replayed
by test_regressions.py.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzz import mutate
from fuzz import seeding as seeds
from fuzz.harness import Worker

pytestmark = pytest.mark.slow  # `make check` leaves these out: see docs/testing.md

EXAMPLES = int(os.environ.get("KINETRE_FUZZ_EXAMPLES", "10"))
LONG = os.environ.get("KINETRE_FUZZ_LONG") == "1"
SETTINGS = settings(max_examples=EXAMPLES, derandomize=not LONG, database=None, deadline=None,
                    suppress_health_check=list(HealthCheck), print_blob=True)


def cases(weight: float) -> settings:
    """SETTINGS with `weight` x KINETRE_FUZZ_EXAMPLES cases: fewer for the slow readers (a rigged glTF runs
    the avatar and motion readers), more for the fast ones."""
    return settings(SETTINGS, max_examples=max(1, round(EXAMPLES * weight)))
COUNTS: dict[str, int] = {}
FOUND = Path(__file__).resolve().parent / "found"


@pytest.fixture(scope="module")
def worker():
    w = Worker()
    yield w
    w.stop()


@pytest.fixture(scope="module")
def seed_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("seeds")


class Blob(bytes):
    """A mutated file whose repr is short: hypothesis prints the failing case, and a file of 100 kB is noise
    (the file itself is kept in found/)."""

    def __repr__(self) -> str:
        return f"<{len(self)} bytes, sha256 {hashlib.sha256(self).hexdigest()[:16]}>"


def blobs(strategy):
    return strategy.map(Blob)


def check(worker: Worker, reader: str, files: dict[str, bytes], main: str) -> None:
    COUNTS[reader] = COUNTS.get(reader, 0) + 1
    outcome = worker.run(reader, files, main)
    if outcome.status not in ("ok", "refused"):
        # keep the case, to reproduce it and make it a regression case (cases/, test_regressions.py)
        digest = hashlib.sha256(b"".join(files[k] for k in sorted(files))).hexdigest()[:16]
        for name, data in files.items():
            target = FOUND / f"{reader}-{digest}" / name
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
        pytest.fail(f"{reader} reader, {main} (kept in {FOUND / f'{reader}-{digest}'}): {outcome.status}: "
                    f"{outcome.detail}")
    _check_message(outcome, main, files)


def _check_message(outcome, main: str, files) -> None:
    if outcome.status == "refused":
        # the message names the file (the reader process writes the case into a kinetre-fuzz-* folder)
        assert "kinetre-fuzz-" in outcome.detail, f"{main}: the refusal does not name the file: {outcome.detail}"


MESHES = seeds.mesh_seeds()
PLY, STL = "shape.ply", "shape.stl"


def mesh_case(name: str):
    data = MESHES[name]
    if name == PLY:
        return mutate.ply_mutation(data)
    if name == STL:
        return mutate.stl_mutation(data)
    if name == "shape.glb":
        return mutate.glb_mutation(data)
    return mutate.text_mutation(data)


@pytest.mark.parametrize("name", sorted(MESHES))
def test_mesh_reader_answers_every_mutation(worker, name):
    """OBJ, PLY (binary and ASCII), STL (binary and ASCII), OFF and GLB meshes."""
    assert worker.run("mesh", {name: MESHES[name]}, name).status == "ok"

    @cases(1.5)
    @given(blobs(mesh_case(name)))
    def run(data):
        check(worker, "mesh", {name: data}, name)
    run()


GLTF = ("rigged.glb", "synthetic.glb", "vrm0.vrm", "vrm1.vrm", "vrma.glb", "embedded.gltf")


@pytest.fixture(scope="module")
def gltf_files(seed_dir):
    return seeds.gltf_seeds(seed_dir)


@pytest.mark.parametrize("name", GLTF)
def test_gltf_readers_answer_every_mutation(worker, gltf_files, name):
    """Rigged and animated GLB, VRM 0.x and 1.0, a VRM Animation, a .gltf with a data-URI buffer: read as a
    mesh, an avatar and a motion."""
    data = gltf_files[name]
    assert worker.run("gltf", {name: data}, name).status in ("ok", "refused")
    if name.endswith(".gltf"):
        import json
        strategy = mutate.json_mutation(json.loads(data), prefer=mutate.gltf_index_path).map(mutate.json_text)
    else:
        strategy = mutate.glb_mutation(data)

    @cases(0.6)
    @given(blobs(strategy))
    def run(mutated):
        check(worker, "gltf", {name: mutated}, name)
    run()


def test_bvh_reader_answers_every_mutation(worker):
    data = seeds.short_bvh()
    assert worker.run("bvh", {"clip.bvh": data}, "clip.bvh").status == "ok"

    @cases(2)
    @given(blobs(mutate.text_mutation(data, 4)))
    def run(mutated):
        check(worker, "bvh", {"clip.bvh": mutated}, "clip.bvh")
    run()


@pytest.mark.parametrize("name", ["body.kinetre.jsonl", "people.kinetre.jsonl"])
def test_take_reader_answers_every_mutation(worker, seed_dir, name):
    data = seeds.take_seeds(seed_dir)[name]
    assert worker.run("take", {name: data}, name).status == "ok"

    @cases(1)
    @given(blobs(mutate.jsonl_mutation(data)))
    def run(mutated):
        check(worker, "take", {name: mutated}, name)
    run()


def test_intrinsics_reader_answers_every_mutation(worker):
    text = mutate.json_text(seeds.INTRINSICS)
    txt = b"36 0 19.5\n0 36 14.5\n0 0 1\n"

    @cases(3)
    @given(st.one_of(mutate.json_mutation(seeds.INTRINSICS).map(mutate.json_text).map(lambda d: ("k.json", d)),
                     mutate.text_mutation(text).map(lambda d: ("k.json", d)),
                     mutate.text_mutation(txt).map(lambda d: ("k.txt", d))).map(lambda c: (c[0], Blob(c[1]))))
    def run(case):
        name, data = case
        check(worker, "intrinsics", {name: data}, name)
    run()


RGBD = seeds.rgbd_seed()


@st.composite
def rgbd_case(draw):
    """The folder with its intrinsics bent, a frame's PNG broken or replaced (8-bit, another size, no depth,
    a huge declared size), a frame missing, or a TUM list in place of the folders."""
    files = dict(RGBD)
    part = draw(st.sampled_from(("intrinsics", "png", "image", "drop", "tum")))
    frames = sorted(k for k in files if k.endswith(".png"))
    if part == "intrinsics":
        files["intrinsics.json"] = mutate.json_text(draw(mutate.json_mutation(seeds.INTRINSICS)))
    elif part == "png":
        k = draw(st.sampled_from(frames))
        files[k] = draw(mutate.bytes_mutation(files[k]))
    elif part == "image":
        import numpy as np
        k = draw(st.sampled_from(frames))
        files[k] = draw(st.sampled_from((
            seeds._png(np.zeros((30, 40), np.uint16)), seeds._png(np.full((30, 40), 200, np.uint8)),
            seeds._png(np.full((7, 5), 1000, np.uint16)), seeds._png(np.full((1, 1), 65535, np.uint16)),
            seeds._png(np.full((30, 40, 3), 9, np.uint8)),
            # a PNG header declaring 100000 x 100000 pixels
            files[k][:16] + bytes.fromhex("000186a0000186a0") + files[k][24:])))
    elif part == "drop":
        del files[draw(st.sampled_from(frames))]
    else:
        stamps = "".join(f"{i * 0.1:.3f} depth/{i:05d}.png\n" for i in range(3)).encode()
        files["depth.txt"] = draw(mutate.text_mutation(stamps))
        files["rgb.txt"] = stamps.replace(b"depth/", b"color/")
    return {k: Blob(v) for k, v in files.items()}


def test_rgbd_reader_answers_every_mutation(worker):
    """RGB-D folders and their intrinsics, through the frame reader and a whole scan (Open3D)."""
    files = {f"frames/{k}": v for k, v in RGBD.items()}
    first = worker.run("rgbd", files, "frames")
    assert first.status in ("ok", "refused"), first.detail

    @cases(1)
    @given(rgbd_case())
    def run(case):
        check(worker, "rgbd", {f"frames/{k}": v for k, v in case.items()}, "frames")
    run()


def test_report_counts():
    """The cases each reader ran in this session (the closing figures of a fuzz run)."""
    print("fuzz cases per reader:", COUNTS, "total", sum(COUNTS.values()))
