// Physics play in a real browser (Debian's Chromium + SwiftShader, driven by playwright-core): the box tower
// beside the sample cow at rest, the cow dragged through it (the "place" message the Move gizmo sends), boxes
// falling, the sphere proxies shown (O), reset by key (X) and by voice ("reset" on the fake microphone),
// dodgeball, a recorded take replayed through the physics into a WebM, and a second mesh whose proxies join
// the world. Prints one JSON object.
//   node driver_physics.mjs '{"url": "...", "audio": "reset.wav", "artifacts": "...", "out": "video.webm"}'
import { mkdirSync, writeFileSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { chromium, moreTransforms, pageNow, report, shownAfter, watchTransforms } from './harness.mjs';

const config = JSON.parse(process.argv[2]);
const result = { steps: [] };
const t0 = Date.now();
const log = (step, extra = {}) => result.steps.push({ step, s: (Date.now() - t0) / 1000, ...extra });
const physics = (page) => page.evaluate(() => window.kinetre.state().physics);
const until = async (page, predicate, arg, timeout = 120000) =>
  (await page.waitForFunction(predicate, arg, { timeout, polling: 200 })).jsonValue();

async function shot(page, file) {
  mkdirSync(config.artifacts, { recursive: true });
  await page.screenshot({ path: join(config.artifacts, file) });
}

/** Drag the cow 1.8 m to the right (through the tower beside it) in 40 moves, as the Move gizmo would. */
function dragRight(page) {
  return page.evaluate(async () => {
    const studio = window.kinetre.studio;
    const { id, placement: p } = studio.selectedState;
    for (let i = 1; i <= 40; i++) {
      studio.socket.send({ type: 'place', mesh: id, scale: p.scale, position: [p.position[0] + 0.045 * i, p.position[1], p.position[2]], yaw: p.yaw });
      await new Promise((r) => setTimeout(r, 75));
    }
  });
}

async function run() {
  const browser = await chromium.launch({
    executablePath: '/usr/bin/chromium', headless: true,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-background-timer-throttling',
      '--disable-renderer-backgrounding', '--use-fake-ui-for-media-stream', '--use-fake-device-for-media-stream',
      `--use-file-for-fake-audio-capture=${resolve(config.audio)}`],
  });
  try {
    const page = await browser.newPage({ viewport: { width: 640, height: 480 } });
    page.on('pageerror', (e) => log('page error', { message: String(e) }));
    await page.goto(`${config.url}/?noshadows&physics=tower`);
    await until(page, () => window.kinetre && window.kinetre.state().physics.boxes.length === 20);
    await watchTransforms(page);
    // stop the sample walk: a possessed mesh follows its skeleton, wherever the placement puts it
    const stopped = await pageNow(page);
    await page.keyboard.press('m');
    await until(page, () => !window.kinetre.state().users.some((u) => u.possessing));
    await shownAfter(page, stopped); // the cow shown at rest
    const built = (await physics(page)).resets;
    await page.keyboard.press('x'); // the tower beside the cow at rest
    await until(page, (n) => window.kinetre.state().physics.resets > n, built);
    const start = await physics(page);
    result.start = { spheres: start.spheres, radii: start.radii, meshes: start.meshes, boxes: start.boxes };
    log('tower built', { spheres: start.spheres });
    await shot(page, 'physics-tower.png');

    await dragRight(page);
    const knocked = await until(page, () => { const p = window.kinetre.state().physics; return p.knockedDown >= 10 && p.steps; });
    await until(page, (n) => window.kinetre.state().physics.steps >= n, knocked + 90); // let them land: 1.5 s simulated
    await page.keyboard.press('o'); // show the spheres
    await until(page, () => window.kinetre.state().physics.showSpheres);
    const hit = await physics(page);
    result.hit = { knockedDown: hit.knockedDown, boxes: hit.boxes, showSpheres: hit.showSpheres, proxies: hit.proxies };
    log('boxes knocked down', { knockedDown: hit.knockedDown });
    await shot(page, 'physics-knocked-down.png');

    await page.keyboard.press('x');
    const reset = await until(page, (n) => { const p = window.kinetre.state().physics; return p.resets > n ? p : null; }, hit.resets);
    result.resetByKey = { knockedDown: reset.knockedDown, boxes: reset.boxes, steps: reset.steps };
    log('reset by key');

    await dragRight(page); // through the rebuilt tower, then say "reset"
    await until(page, () => window.kinetre.state().physics.knockedDown >= 5);
    const { knockedDown: before, resets } = await physics(page);
    await page.keyboard.press('v');
    const voice = await until(page, () => {
      const s = window.kinetre.state();
      return s.voice && s.voice.command && s.voice.command.verb === 'reset' ? { voice: s.voice, physics: s.physics } : null;
    }, null, 90000);
    await page.keyboard.press('v');
    result.resetByVoice = { heard: voice.voice.command.text, before, knockedDown: voice.physics.knockedDown,
      rebuilt: voice.physics.resets - resets };
    log('reset by voice');

    await page.selectOption('#physics-preset', 'dodgeball');
    const balls = await until(page, () => { const p = window.kinetre.state().physics; return p.balls >= 3 ? p : null; });
    result.dodgeball = { balls: balls.balls, boxes: balls.boxes.length };
    await shot(page, 'physics-dodgeball.png');
    log('dodgeball');

    // a take of the sample motion, replayed through a box tower into a WebM
    await page.selectOption('#physics-preset', 'tower');
    await page.keyboard.press('m');
    await until(page, () => window.kinetre.state().users.some((u) => u.possessing));
    await page.keyboard.press(' ');
    await until(page, () => window.kinetre.state().recording);
    await moreTransforms(page, 30); // poses solved while recording (the take keeps each)
    await page.keyboard.press(' ');
    await until(page, () => !document.querySelector('#physics-replay').disabled, null, 240000);
    await page.click('#physics-replay');
    const replay = await until(page, () => window.kinetre.state().physics.lastReplay, null, 240000);
    result.replay = replay;
    const video = await page.evaluate(async () => {
      const a = document.querySelector('#physics-video');
      const bytes = new Uint8Array(await (await fetch(a.href)).arrayBuffer());
      let s = '';
      for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
      return { name: a.download, hidden: a.hidden, b64: btoa(s) };
    });
    writeFileSync(config.out, Buffer.from(video.b64, 'base64'));
    // the take and the mesh as the page got them, for the same replay in node
    const take = await page.evaluate(async () => {
      const s = window.kinetre.state();
      const [recorded] = s.take.meshes; // the scene's one mesh, its files named by its id
      const bytes = new Uint8Array(await (await fetch(recorded.files.transforms.replace(/^\//, ''))).arrayBuffer());
      let b = '';
      for (let i = 0; i < bytes.length; i += 0x8000) b += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
      const mesh = await (await fetch(`api/mesh/${recorded.id}`)).text();
      return { transforms: btoa(b), mesh, fps: s.take.fps, id: recorded.id, file: recorded.files.transforms };
    });
    writeFileSync(config.takeTransforms, Buffer.from(take.transforms, 'base64'));
    writeFileSync(config.takeMesh, take.mesh);
    result.take = { fps: take.fps, id: take.id, file: take.file };
    result.video = { name: video.name, hidden: video.hidden, file: config.out };
    await shot(page, 'physics-replayed.png');
    log('replayed');

    // a second mesh added beside the cow: its proxies join the world (every mesh pushes the boxes), and
    // selecting it in the mesh list gives it the gizmo
    await page.setInputFiles('#file-add', resolve(config.add));
    const both = await until(page, () => { const p = window.kinetre.state().physics; return p.meshes.length === 2 ? p : null; },
      null, 240000);
    const ids = await page.evaluate(() => window.kinetre.state().meshes.map((m) => m.id));
    await page.check(`#mesh-list input[data-mesh="${ids[1]}"]`);
    const selected = await until(page, (id) => { const s = window.kinetre.state(); return s.meshId === id ? s.meshId : null; }, ids[1]);
    result.added = { meshes: both.meshes, spheres: both.spheres, boxes: both.boxes.length, ids, selected };
    log('mesh added');
  } finally {
    await browser.close();
  }
}

await report(result, run, { t0 });
