"""Spoken test commands, synthesised at test time with Debian's festival voices (no audio in the repository).

espeak-ng's voices are not used: pocketsphinx misses espeak-ng's lone "possess" in every voice.
"""
from __future__ import annotations

import subprocess
from pathlib import Path

# Name → festival voice function: a female HTS voice (32 kHz) and a male diphone voice (16 kHz).
VOICES = {"slt": "voice_cmu_us_slt_arctic_hts", "kal": "voice_kal_diphone"}

# Speech that is not a command: must not come back as one.
OUT_OF_GRAMMAR = ("hello world", "what time is it", "open the door please", "play some music",
                  "the weather is nice today", "turn on the lights", "good morning everyone",
                  "can you hear me", "I like coffee", "stop the recording")


def command_texts(subsets: tuple[str, ...]) -> list[tuple[str, str | None, str | None]]:
    """(text, verb, subset) for {possess, release} x {nothing, "the" + each subset}, then each bare subset."""
    verbs = ("possess", "release")
    return ([(v, v, None) for v in verbs] + [(f"{v} the {s}", v, s) for v in verbs for s in subsets]
            + [(s, None, s) for s in subsets])


# The grammar's other words for the two verbs.
SYNONYMS = (("attach", "possess", None), ("let go", "release", None),
            ("attach the right arm", "possess", "right arm"), ("let go the legs", "release", "legs"))


def synthesise(texts: list[str], voice: str, directory: Path) -> list[bytes]:
    """WAV bytes of each text spoken by festival `voice` (a key of VOICES); one festival run for all."""
    directory.mkdir(parents=True, exist_ok=True)
    paths = [directory / f"{voice}_{i:03d}.wav" for i in range(len(texts))]
    script = [f"({VOICES[voice]})"]
    for text, path in zip(texts, paths):
        clean = text.replace('"', "").replace("\\", "")
        script.append(f'(utt.save.wave (utt.synth (Utterance Text "{clean}")) "{path}" \'riff)')
    scm = directory / f"{voice}.scm"
    scm.write_text("\n".join(script) + "\n")
    subprocess.run(["festival", "-b", str(scm)], check=True, capture_output=True, timeout=300)
    return [p.read_bytes() for p in paths]


def looped_command_wav(text: str, directory: Path) -> Path:
    """Festival (kal) saying `text` as 16 kHz mono WAV with 0.5 s of silence before and 1.5 s after: what a
    browser's fake microphone loops in the e2e tests."""
    directory.mkdir(parents=True, exist_ok=True)
    raw, wav = directory / "raw.wav", directory / f"{text.replace(' ', '_')}.wav"
    subprocess.run(["text2wave", "-o", str(raw), "-eval", "(voice_kal_diphone)"], input=text.encode(), check=True,
                   capture_output=True)
    subprocess.run(["sox", str(raw), "-r", "16000", "-c", "1", "-b", "16", str(wav), "pad", "0.5", "1.5"],
                   check=True, capture_output=True)
    return wav
