"""Physics play (KinÊtre paper, "Physics-based Interactions"): sphere packing time, and one step of the
page's Rapier world.

Prints JSON lines:
  {"bench": "physics", "what": "pack", ...}   pack_spheres on each shared mesh: the paper's rule and the
                                               studio's 256-sphere budget (count, radius factor, ms)
  {"bench": "physics", "what": "step", "where": "node" | "chromium", ...}
                                               ms per world step (proxies moved + Rapier step) with S kinematic
                                               spheres sweeping through B boxes, the module the page runs
                                               (web/src/physics/PhysicsWorld.ts), in node and in Debian's
                                               headless Chromium (the page's WASM engine; target ≤ 4 ms).
                                               Wall-clock ms (median, p90, mean) and, in node, CPU ms per step
                                               (cpu_ms_mean), which a loaded machine does not inflate.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import kinetre
from kinetre.physics.spheres import STUDIO_MAX_SPHERES, pack_spheres

ROOT = Path(__file__).resolve().parents[1]
WEB = ROOT / "web"
DATA = ROOT / ".." / "shared" / "data" / "meshes"
CASES = [(200, (5, 5, 4)), (STUDIO_MAX_SPHERES, (5, 5, 4))]  # (spheres, box grid): 100 boxes
STEPS, WARMUP = 600, 60

BROWSER = r"""
import { createRequire } from 'node:module';
const require = createRequire(process.argv[2]);
const { chromium } = require('playwright-core');
const [, , , bundle, configs] = process.argv;
const browser = await chromium.launch({ executablePath: '/usr/bin/chromium', headless: true,
  args: ['--headless', '--no-sandbox', '--disable-gpu'] });
try {
  const page = await browser.newPage();
  for (const config of JSON.parse(configs)) {
    await page.goto('about:blank');
    await page.evaluate((c) => { window.physicsBenchConfig = c; }, config);
    await page.addScriptTag({ path: bundle });
    console.log(JSON.stringify(await page.evaluate(() => window.physicsBench)));
  }
} finally {
  await browser.close();
}
"""


def emit(record: dict) -> None:
    print(json.dumps({"bench": "physics", **record}), flush=True)


def bench_packing() -> None:
    for path in sorted(p for p in DATA.iterdir() if not p.name.endswith(".md")):
        mesh = kinetre.load_mesh(path)
        for budget in (None, STUDIO_MAX_SPHERES):
            t = time.perf_counter()
            packing = pack_spheres(mesh, max_spheres=budget)
            emit({"what": "pack", "mesh": path.name, "vertices": len(mesh.vertices), "max_spheres": budget,
                  "spheres": packing.count, "factor": round(packing.factor, 2),
                  "ms": round(1000 * (time.perf_counter() - t), 1)})


def bundle(folder: Path, fmt: str) -> Path:
    out = folder / f"physics_step.{fmt}.js"
    subprocess.run([str(WEB / "node_modules" / ".bin" / "esbuild"), str(ROOT / "benchmarks" / "physics_step.ts"),
                    "--bundle", f"--format={fmt}", "--platform=" + ("node" if fmt == "esm" else "browser"),
                    f"--outfile={out}", "--log-level=error"], check=True, cwd=WEB, timeout=120)
    return out


def bench_step(folder: Path) -> None:
    configs = [{"spheres": s, "boxes": list(b), "steps": STEPS, "warmup": WARMUP} for s, b in CASES]
    node = bundle(folder, "esm")
    for config in configs:
        out = subprocess.run(["node", str(node), json.dumps(config)], capture_output=True, text=True, timeout=300,
                             check=True)
        emit({"what": "step", "where": "node", **json.loads(out.stdout)})
    script = folder / "browser.mjs"
    script.write_text(BROWSER)
    out = subprocess.run(["node", str(script), str(WEB / "package.json"), str(bundle(folder, "iife")),
                          json.dumps(configs)], capture_output=True, text=True, timeout=600)
    if out.returncode != 0:
        emit({"what": "step", "where": "chromium", "error": out.stderr.strip().splitlines()[-1:]})
        return
    for line in out.stdout.strip().splitlines():
        emit({"what": "step", "where": "chromium", **json.loads(line)})


if __name__ == "__main__":
    bench_packing()
    with tempfile.TemporaryDirectory() as folder:
        bench_step(Path(folder))
    sys.exit(0)
