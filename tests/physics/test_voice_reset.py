"""The voice command "reset" (the page rebuilds its physics scene): festival speech is recognised as it."""
import pytest

from kinetre.studio.voice import Command, Recogniser
from studio.fixtures_voice import VOICES, synthesise

pytestmark = pytest.mark.slow  # speech synthesised by festival in a subprocess: see docs/testing.md


@pytest.mark.parametrize("voice", sorted(VOICES))
def test_reset_is_recognised(voice, tmp_path):
    recogniser = Recogniser()
    said, other = synthesise(["reset", "release"], voice, tmp_path)
    assert recogniser.recognise(said) == Command("reset", None, "reset")
    assert recogniser.recognise(other) == Command("release", None, "release")  # a near word stays itself
