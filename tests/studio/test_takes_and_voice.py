"""Recording a take (GLB, BVH, skeleton stream) and voice commands through the studio server."""
import asyncio
import io
import json
import subprocess

import httpx
import numpy as np
import pygltflib
import pytest
from studio.studio_ws import StudioClient, frame_message, possessed_client


def festival_wav(tmp_path, text: str) -> bytes:
    """`text` spoken by Debian's festival (kal diphone voice) as 16 kHz mono WAV."""
    raw = tmp_path / "raw.wav"
    out = tmp_path / "speech.wav"
    subprocess.run(["text2wave", "-o", str(raw), "-eval", "(voice_kal_diphone)"], input=text.encode(),
                   check=True, capture_output=True)
    subprocess.run(["sox", str(raw), "-r", "16000", "-c", "1", "-b", "16", str(out), "pad", "0.3", "0.3"],
                   check=True, capture_output=True)
    return out.read_bytes()


def test_a_recorded_take_downloads_as_glb_bvh_and_stream(studio, walk):
    async def go():
        c = await possessed_client(studio, walk)
        try:
            async with httpx.AsyncClient(base_url=studio, timeout=120) as http:
                assert (await http.post("/api/record/start")).json() == {"recording": True}
                for i in range(1, 45):
                    await c.send(frame_message(i + 1, walk[i]))
                    await asyncio.sleep(1 / 30)
                await asyncio.sleep(0.5)
                take = (await http.post("/api/record/stop")).json()
                [mesh] = take["meshes"]  # the one mesh that moved, its files by kind
                files = {k: (await http.get(v)) for k, v in mesh["files"].items()}
                empty = await http.post("/api/record/stop")
            return take, files, empty
        finally:
            await c.__aexit__(None, None, None)

    take, files, empty = asyncio.run(go())
    assert take["fps"] == 30 and take["frames"] >= 10
    assert all(r.status_code == 200 for r in files.values())
    mesh_id = take["meshes"][0]["id"]  # its files are named by its id, as every mesh's are
    assert {k: v.rsplit("/", 1)[1] for k, v in take["files"].items()} == {
        f"{kind}-{mesh_id}": f"take-mesh{mesh_id}.{ext}"
        for kind, ext in [("glb", "glb"), ("transforms", "transforms"), ("bvh", "bvh"), ("stream", "kinetre.jsonl")]}
    glb = pygltflib.GLTF2.load_from_bytes(files["glb"].content)
    nodes = httpx.get(studio + "/api/state").json()["meshes"][0]["nodes"]
    assert len(glb.skins) == 1 and len(glb.skins[0].joints) == nodes
    times = glb.accessors[glb.animations[0].samplers[0].input]
    assert times.count == take["frames"]
    assert files["bvh"].text.startswith("HIERARCHY") and "MOTION" in files["bvh"].text
    lines = files["stream"].text.strip().splitlines()
    assert len(lines) == take["frames"] + 1 and json.loads(lines[0])  # a header, then one line per frame
    assert empty.status_code == 400 and "empty" in empty.json()["error"]


@pytest.mark.parametrize("text, verb, subset", [("possess", "possess", None), ("release", "release", None)])
def test_voice_commands_possess_and_release(studio, walk, tmp_path, text, verb, subset):
    wav = festival_wav(tmp_path, text)

    async def go():
        async with StudioClient(studio) as c:
            await c.send(frame_message(1, walk[0]))
            await c.wait(lambda c: c.me() and c.me()["frames"] >= 1)
            await c.send({"type": "fit"})
            if verb == "release":
                await c.send({"type": "possess"})
                await c.wait(lambda c: c.me()["possessing"], 60)
            async with httpx.AsyncClient(base_url=studio, timeout=60) as http:
                reply = (await http.post(f"/api/voice?client={c.client}", content=wav)).json()
            await c.wait(lambda c: c.me()["possessing"] == (verb == "possess"), 60)
            return reply

    reply = asyncio.run(go())
    assert reply["command"] == {"verb": verb, "subset": subset, "text": text}


def test_voice_rejects_audio_that_is_not_wav(studio):
    r = httpx.post(studio + "/api/voice?client=nobody", content=b"definitely not audio", timeout=60)
    assert r.status_code == 400 and r.json()["error"]


def test_silence_is_no_command(studio):
    buf = io.BytesIO()
    from scipy.io import wavfile
    wavfile.write(buf, 16000, np.zeros(16000, np.int16))
    r = httpx.post(studio + "/api/voice?client=nobody", content=buf.getvalue(), timeout=60)
    assert r.status_code == 200 and r.json() == {"command": None}
