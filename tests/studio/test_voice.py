"""Voice commands: festival speech of every command is recognised; silence, noise and chatter are not."""
from __future__ import annotations

import dataclasses
import io

import numpy as np
import pytest
from scipy.io import wavfile
from scipy.signal import resample_poly

import kinetre
from kinetre.studio.voice import (BadAudioError, Command, Recogniser, command_sentences, pcm16k,
                                  recognise)
from studio.fixtures_voice import OUT_OF_GRAMMAR, SYNONYMS, VOICES, command_texts, synthesise

pytestmark = pytest.mark.slow  # speech synthesised by festival in a subprocess: see docs/testing.md


@pytest.fixture(scope="module")
def recogniser():
    return Recogniser()


@pytest.fixture(scope="module")
def speech(tmp_path_factory):
    """{voice: (items, wavs)} with items = commands + synonyms + out-of-grammar sentences."""
    items = command_texts(kinetre.subset_names()) + list(SYNONYMS) + [(t, None, None) for t in OUT_OF_GRAMMAR]
    directory = tmp_path_factory.mktemp("speech")
    return {voice: (items, synthesise([t for t, _, _ in items], voice, directory)) for voice in VOICES}


def decoded(recogniser, speech, texts):
    """[(voice, text, expected verb, expected subset, Command | None)] for the items whose text is in texts."""
    return [(voice, text, verb, subset, recogniser.recognise(wav))
            for voice, (items, wavs) in speech.items()
            for (text, verb, subset), wav in zip(items, wavs) if text in texts]


@pytest.mark.slow
def test_every_command_in_both_festival_voices(recogniser, speech):
    texts = {t for t, _, _ in command_texts(kinetre.subset_names())}
    results = decoded(recogniser, speech, texts)
    assert len(results) == 2 * 32
    wrong = [(v, t, c) for v, t, verb, subset, c in results
             if c is None or (c.verb, c.subset) != (verb, subset)]
    rate = 1 - len(wrong) / len(results)
    print(f"\nrecognition rate {rate:.1%} ({len(results) - len(wrong)}/{len(results)}); wrong: {wrong}")
    assert rate >= 0.95, wrong
    for v, t, verb, subset, c in results:
        if t in ("possess", "release"):
            assert c == Command(verb, None, t), (v, t, c)


def test_synonyms_attach_and_let_go(recogniser, speech):
    results = decoded(recogniser, speech, {t for t, _, _ in SYNONYMS})
    assert len(results) == 2 * len(SYNONYMS)
    for v, t, verb, subset, c in results:
        assert c is not None and (c.verb, c.subset, c.text) == (verb, subset, t), (v, t, c)


@pytest.mark.slow
def test_out_of_grammar_speech_is_rarely_a_command(recogniser, speech):
    results = decoded(recogniser, speech, set(OUT_OF_GRAMMAR))
    assert len(results) == 2 * len(OUT_OF_GRAMMAR)
    accepted = [(v, t, c.text) for v, t, _, _, c in results if c is not None]
    print(f"\nfalse accepts {len(accepted)}/{len(results)}: {accepted}")
    assert len(accepted) <= 2, accepted


@pytest.mark.slow
def test_silence_and_noise_are_not_commands(recogniser):
    rng = np.random.default_rng(0)
    second = 16000
    assert recogniser.recognise(np.zeros(second, np.int16)) is None
    assert recogniser.recognise(np.zeros(second, np.float32)) is None
    for rms in (0.001, 0.03, 0.1, 0.3):  # -60 dBFS hiss up to loud white noise
        noise = np.clip(rng.standard_normal(2 * second) * rms, -1, 1)
        assert recogniser.recognise(noise) is None, rms
    brown = np.cumsum(rng.standard_normal(2 * second))  # rumble: energy in the speech band's low end
    assert recogniser.recognise(0.3 * brown / np.abs(brown).max()) is None


def test_44k1_input_is_resampled_and_recognised(recogniser, speech):
    items, wavs = speech["slt"]
    wav = wavs[[t for t, _, _ in items].index("release the left leg")]
    rate, pcm = wavfile.read(io.BytesIO(wav))
    assert rate == 32000  # the HTS voice speaks at 32 kHz: the WAV path resamples too
    pcm44 = resample_poly(pcm.astype(np.float64) / 32768, 441, 320)
    expected = Command("release", "left leg", "release the left leg")
    assert recogniser.recognise(pcm44, 44100) == expected
    assert recogniser.recognise(np.round(pcm44 * 32767).astype(np.int16), sample_rate=44100) == expected
    buffer = io.BytesIO()
    wavfile.write(buffer, 44100, (pcm44 * 32767).astype(np.int16))
    assert recogniser.recognise(buffer.getvalue()) == expected
    out = pcm16k(pcm44, 44100)
    assert out.dtype == np.int16 and abs(out.size - pcm.size / 2) <= 1


def test_stereo_float_wav_and_int16_passthrough(recogniser, speech):
    items, wavs = speech["kal"]
    wav = wavs[[t for t, _, _ in items].index("upper body")]
    rate, pcm = wavfile.read(io.BytesIO(wav))
    assert rate == 16000
    assert np.array_equal(pcm16k(pcm), pcm)  # 16 kHz int16 goes through bit for bit
    stereo = np.stack([pcm, pcm], axis=1).astype(np.float32) / 32768
    buffer = io.BytesIO()
    wavfile.write(buffer, 22050, resample_poly(stereo, 441, 320, axis=0).astype(np.float32))
    assert recogniser.recognise(buffer.getvalue()) == Command(None, "upper body", "upper body")


def test_convenience_function_matches_recogniser(recogniser, speech):
    items, wavs = speech["kal"]
    wav = wavs[[t for t, _, _ in items].index("possess the arms")]
    assert recognise(wav, recogniser=recogniser) == Command("possess", "arms", "possess the arms")
    assert recognise(wav) == recogniser.recognise(wav)


def test_command_is_frozen_and_grammar_covers_every_subset():
    sentences = command_sentences(kinetre.subset_names())
    assert len(sentences) == 4 * (1 + 2 * 10) + 10 + 1  # + "reset"
    assert {c.subset for c in sentences.values()} == set(kinetre.subset_names()) | {None}
    assert sentences["let go the spine"] == Command("release", "spine", "let go the spine")
    with pytest.raises(dataclasses.FrozenInstanceError):
        sentences["possess"].verb = "release"


@pytest.mark.parametrize("audio, rate, match", [
    (b"RIFF....WAVEnope", 16000, "not a readable WAV"),
    (b"", 16000, "not a readable WAV"),
    (np.zeros((2, 1600), np.int16), 16000, r"1-D mono PCM, got shape \(2, 1600\)"),
    (np.zeros(1600, np.int32), 16000, "int16 or float samples, got int32"),
    (np.full(1600, np.nan), 16000, "NaN"),
    (np.zeros(11 * 16000, np.int16), 16000, "11.0 s of audio"),
    (np.zeros(1600, np.int16), 400, "400 Hz is too low"),
    ("possess", 16000, "WAV bytes or a numpy array, got str"),
])
def test_bad_audio_names_the_problem(recogniser, audio, rate, match):
    with pytest.raises(BadAudioError, match=match):
        recogniser.recognise(audio, rate)
    assert issubclass(BadAudioError, kinetre.KinetreError)
