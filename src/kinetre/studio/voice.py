"""Offline voice commands ("possess", "release the left arm", "upper body") with pocketsphinx.

The page sends one utterance of microphone audio; `Recogniser.recognise` decodes it against a small JSGF
grammar built from the joint subset names and returns a `Command`, or None for silence, noise and speech
that is not a command.

Grammar: a verb ("possess" | "attach" → possess, "release" | "let go" → release), then optionally
[the] and a body part; or a bare body part; or "reset" alone (the page resets its physics scene).
Out-of-grammar speech is rejected with a garbage model in the same search: a loop of phone "words"
competes with the commands, so "what time is it" is absorbed by the loop instead of being forced onto
the nearest command. Without the loop most out-of-grammar sentences come back as commands; the price
is some noise robustness and a longer decode (figures on festival speech: benchmarks/bench_voice.py).

    >>> rec = Recogniser()                                              # doctest: +SKIP
    >>> rec.recognise(open("possess.wav", "rb").read())                 # doctest: +SKIP
    Command(verb='possess', subset=None, text='possess')
"""
from __future__ import annotations

import io
import itertools
import os
import re
import threading
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.io import wavfile
from scipy.signal import resample_poly

from ..errors import KinetreError
from ..skeleton.subsets import subset_names

SAMPLE_RATE = 16000  # the acoustic model in the pocketsphinx wheel is 16 kHz
MAX_SECONDS = 10.0  # one command; longer input is a stream the page should have cut into utterances
# Frames (20 ms) quieter than this everywhere mean nobody spoke: skip the decoder. -50 dBFS is well
# below speech at any usable microphone gain and above a quiet room's hiss.
MIN_LEVEL_DBFS = -50.0

# Spoken verb → command verb.
VERBS = {"possess": "possess", "attach": "possess", "release": "release", "let go": "release"}
# Whole-scene actions, said alone (no body part): "reset" rebuilds the physics scene in the page.
ACTIONS = {"reset": "reset"}

# Garbage loop: a dozen broad-class phones (vowels front/back/central, fricative, stops, nasal, liquids)
# cover English well enough to out-score a forced command on other speech; all 39 phones cost ~7x the
# decode time and missed 5 of 64 commands. The weight is a weak prior next to the acoustic scores: on our
# fixtures 1 accepted 3 of 30 non-commands, 1e-6 one (a near-rhyme: "please" -> "legs"), 1e-20 the same.
GARBAGE_PHONES = ("AA", "IY", "UW", "EH", "AH", "S", "T", "N", "L", "R", "M", "K")
GARBAGE_WEIGHT = 1e-6


class BadAudioError(KinetreError):
    """Audio handed to the voice recogniser is not a WAV file or a 1-D PCM array."""


@dataclass(frozen=True)
class Command:
    """A recognised voice command.

    verb : "possess" | "release" | "reset" | None — None for a bare body part ("left arm": change the subset).
    subset : one of kinetre.subset_names(), or None when no body part was said.
    text : the recognised words, e.g. "release the left arm".
    """

    verb: str | None
    subset: str | None
    text: str


def command_sentences(subsets: tuple[str, ...]) -> dict[str, Command]:
    """Every sentence of the grammar, mapped to its Command (the grammar and the parser share this table)."""
    out: dict[str, Command] = {}
    for spoken, verb in VERBS.items():
        out[spoken] = Command(verb, None, spoken)
        for part, the in itertools.product(subsets, ("", "the ")):
            text = f"{spoken} {the}{part}"
            out[text] = Command(verb, part, text)
    for part in subsets:
        out[part] = Command(None, part, part)
    for spoken, verb in ACTIONS.items():
        out[spoken] = Command(verb, None, spoken)
    return out


def jsgf_grammar(subsets: tuple[str, ...], garbage_words: tuple[str, ...], garbage_weight: float) -> str:
    """The JSGF text: commands in parallel with a weighted loop of garbage (phone) words."""
    parts = " | ".join(subsets)
    verbs = " | ".join(VERBS)
    garbage = " | ".join(garbage_words)
    weight = np.format_float_positional(garbage_weight, trim="-")  # JSGF weights take no exponent
    return (
        "#JSGF V1.0;\n"
        "grammar kinetre;\n"
        f"public <utterance> = /{weight}/ <command> | /1/ <garbage>;\n"
        "<command> = <verb> [[the] <part>] | <part> | <action>;\n"
        f"<verb> = {verbs};\n"
        f"<action> = {' | '.join(ACTIONS)};\n"
        f"<part> = {parts};\n"
        f"<garbage> = ({garbage})+;\n"
    )


def pcm16k(audio: bytes | np.ndarray, sample_rate: int = SAMPLE_RATE, source: str = "audio") -> np.ndarray:
    """Audio as (n,) int16 mono PCM at 16 kHz.

    audio : WAV file bytes (any rate; PCM 8/16/32-bit or float, channels averaged; its header's rate
        wins over `sample_rate`), or a 1-D numpy array: int16 PCM, or float in [-1, 1].
    sample_rate : rate of a numpy array in Hz; resampled with a polyphase filter when not 16000.
    """
    if isinstance(audio, (bytes, bytearray, memoryview)):
        try:
            with warnings.catch_warnings():  # unknown chunks (LIST, fact) are skipped, not a problem
                warnings.simplefilter("ignore", wavfile.WavFileWarning)
                sample_rate, data = wavfile.read(io.BytesIO(bytes(audio)))
        except (ValueError, EOFError, OSError) as exc:
            raise BadAudioError(f"{source}: not a readable WAV file ({exc})") from None
        scale = {"u1": 1 / 128, "i2": 1 / 32768, "i4": 1 / 2147483648}
        key = f"{data.dtype.kind}{data.dtype.itemsize}"
        if data.dtype.kind == "f":
            x = data.astype(np.float64)
        elif key == "u1":
            x = (data.astype(np.float64) - 128) * scale[key]
        elif key in scale:
            x = data.astype(np.float64) * scale[key]
        else:
            raise BadAudioError(f"{source}: unsupported WAV sample type {data.dtype}")
        if x.ndim == 2:  # (n, channels): speech is the same in every channel
            x = x.mean(axis=1)
    elif isinstance(audio, np.ndarray):
        if audio.ndim != 1:
            raise BadAudioError(f"{source}: expected 1-D mono PCM, got shape {audio.shape}")
        if audio.dtype == np.int16:
            x = audio.astype(np.float64) / 32768
        elif audio.dtype.kind == "f":
            x = audio.astype(np.float64)
        else:
            raise BadAudioError(f"{source}: expected int16 or float samples, got {audio.dtype}")
    else:
        raise BadAudioError(f"{source}: expected WAV bytes or a numpy array, got {type(audio).__name__}")
    if not np.all(np.isfinite(x)):
        raise BadAudioError(f"{source}: samples contain NaN or infinity")
    sample_rate = int(sample_rate)
    if sample_rate < 8000:
        raise BadAudioError(f"{source}: sample rate {sample_rate} Hz is too low for speech (need >= 8000)")
    if x.size > MAX_SECONDS * sample_rate:
        raise BadAudioError(
            f"{source}: {x.size / sample_rate:.1f} s of audio; a voice command must be under {MAX_SECONDS:g} s")
    if sample_rate != SAMPLE_RATE:
        g = np.gcd(SAMPLE_RATE, sample_rate)
        x = resample_poly(x, SAMPLE_RATE // g, sample_rate // g)
    return np.clip(np.round(x * 32768), -32768, 32767).astype(np.int16)


def peak_level_dbfs(pcm: np.ndarray, frame: int = SAMPLE_RATE // 50) -> float:
    """Loudest 20 ms frame of (n,) int16 PCM, in dB relative to full scale (-inf for digital silence)."""
    n = pcm.size // frame
    if n == 0:
        return -np.inf
    frames = pcm[: n * frame].astype(np.float64).reshape(n, frame) / 32768
    rms = np.sqrt(np.max(np.mean(frames**2, axis=1)))
    return 20 * np.log10(rms) if rms > 0 else -np.inf


def pronunciations(words: set[str], dictionary: str) -> dict[str, str]:
    """{word or "word(2)": "P H O N E S"} for `words` (and their alternative pronunciations) in a CMU
    dictionary file."""
    with open(dictionary, "rb") as f:
        text = f.read().decode("utf-8")
    names = "|".join(re.escape(w) for w in sorted(words))
    return {m[1]: m[2].strip() for m in re.finditer(rf"^((?:{names})(?:\(\d+\))?) ([^\n]+)$", text, re.M)}


class Recogniser:
    """A pocketsphinx decoder loaded once with the command grammar; `recognise` per utterance.

    subsets : body-part names the grammar accepts (default kinetre.subset_names()); every word must be
        in the pocketsphinx English dictionary.
    garbage_weight : prior of a command relative to the garbage loop; lower rejects a little more
        out-of-grammar speech (a weak knob: the acoustic match decides most utterances).

    Thread-safe: one decoder, used under a lock.
    """

    def __init__(self, subsets: tuple[str, ...] | None = None, garbage_weight: float = GARBAGE_WEIGHT):
        try:
            from pocketsphinx import Decoder, get_model_path
        except ImportError:
            raise KinetreError("voice commands need pocketsphinx: pip install 'kinetre[voice]'") from None
        if not (np.isfinite(garbage_weight) and garbage_weight > 0):
            raise KinetreError(f"voice grammar: garbage_weight must be a positive number, got {garbage_weight}")
        self.subsets = tuple(subset_names() if subsets is None else subsets)
        self.sentences = command_sentences(self.subsets)
        model = get_model_path()
        # No language model and no full dictionary: the grammar's few words are added by hand, which
        # makes loading quick enough for `recognise` without a Recogniser to stay usable.
        self._decoder = Decoder(hmm=os.path.join(model, "en-us", "en-us"), dict=None, lm=None,
                                samprate=SAMPLE_RATE, logfn=os.devnull)
        words = {w for text in self.sentences for w in text.split()}
        found = pronunciations(words, os.path.join(model, "en-us", "cmudict-en-us.dict"))
        unknown = sorted(words - {w.split("(")[0] for w in found})
        if unknown:
            raise KinetreError(f"voice grammar: no pronunciation for {', '.join(unknown)}; rename the subset")
        for word, phones in found.items():
            self._decoder.add_word(word, phones, False)
        garbage = tuple(f"garbage_{p.lower()}" for p in GARBAGE_PHONES)
        for word, phone in zip(garbage, GARBAGE_PHONES):
            self._decoder.add_word(word, phone, False)
        self._decoder.add_jsgf_string("commands", jsgf_grammar(self.subsets, garbage, garbage_weight))
        self._decoder.activate_search("commands")
        self._lock = threading.Lock()

    def recognise(self, audio: bytes | np.ndarray, sample_rate: int = SAMPLE_RATE) -> Command | None:
        """The command spoken in one utterance, or None (silence, noise, or not a command).

        audio : WAV bytes or a 1-D int16/float PCM array (see `pcm16k`); sample_rate : its rate in Hz.
        """
        pcm = pcm16k(audio, sample_rate)
        if peak_level_dbfs(pcm) < MIN_LEVEL_DBFS:
            return None
        # Clips cut tight at the last phone end mid-path ("attach" + its release heard as "the"): the
        # grammar's closing silence needs a few frames of quiet to reach the final state.
        pad = np.zeros(SAMPLE_RATE // 4, np.int16)
        pcm = np.concatenate([pad, pcm, pad])
        with self._lock:
            self._decoder.start_utt()
            self._decoder.process_raw(pcm.tobytes(), no_search=False, full_utt=True)
            self._decoder.end_utt()
            hyp = self._decoder.hyp()
        if hyp is None:
            return None
        # Only a complete sentence of the grammar counts: the garbage loop's words and the partial path
        # pocketsphinx returns when no final state was reached ("let go the") both fall out here.
        return self.sentences.get(" ".join(hyp.hypstr.split()))


def recognise(audio: bytes | np.ndarray, sample_rate: int = SAMPLE_RATE, *,
              recogniser: Recogniser | None = None) -> Command | None:
    """`Recogniser.recognise` as a function. Without `recogniser` a decoder is loaded for this one call
    (its cost is "init_ms" in benchmarks/bench_voice.py, about half a decode): hold a Recogniser to recognise
    many utterances."""
    return (recogniser or Recogniser()).recognise(audio, sample_rate)
