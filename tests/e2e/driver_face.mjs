// Drives the studio's face features in Debian's Chromium (playwright-core) and prints one JSON object.
// Run by tests/e2e/test_face_page.py:  node driver_face.mjs '{"scenario": "face"|"annotate", ...}'
// The fake camera plays a face video (a y4m made from the shared portrait, panned and rolled).
import { mkdirSync, readFileSync, writeFileSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { chromium, report } from './harness.mjs';

const config = JSON.parse(process.argv[2]);
const result = { scenario: config.scenario, steps: [] };
const t0 = Date.now();
const log = (step, extra = {}) => result.steps.push({ step, s: (Date.now() - t0) / 1000, ...extra });

async function openPage(path) {
  const browser = await chromium.launch({ executablePath: '/usr/bin/chromium', headless: true, args: [
    '--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-background-networking',
    '--disable-background-timer-throttling', '--disable-renderer-backgrounding',
    '--use-fake-ui-for-media-stream', '--use-fake-device-for-media-stream',
    `--use-file-for-fake-video-capture=${resolve(config.video)}`,
  ] });
  const page = await browser.newPage({ viewport: { width: 720, height: 540 } });
  page.on('pageerror', (e) => log('page error', { message: String(e) }));
  page.on('console', (m) => { if (m.type() === 'error') log('console error', { message: m.text() }); });
  await page.goto(config.url + path);
  return { browser, page };
}

const faceState = (page) => page.evaluate(() => window.kinetreFace.state());

async function face() {
  const { browser, page } = await openPage('/?noshadows');
  try {
    await page.waitForFunction(() => window.kinetre && window.kinetre.state().meshId !== null && window.kinetreFace
      && window.kinetreFace.face.template !== null, null, { timeout: 60000 });
    // the page's Algorithm 2 on landmarks tracked in Python (same numbers as kinetre.face.reconstruct?)
    result.reconstructed = await page.evaluate((cases) => cases.map((c) =>
      window.kinetreFace.reconstruct(c.landmarks, c.width, c.height)), config.cases);
    await page.keyboard.press('g');
    await page.waitForFunction(() => window.kinetreFace.state().tracked >= 3, null, { timeout: 180000, polling: 250 });
    log('face tracked', await faceState(page));
    const samples = [];
    for (let i = 0; i < 12; i++) {
      const s = await faceState(page);
      samples.push({ vertices: s.vertices, uvs: s.uvs, tracked: s.tracked });
      await page.waitForTimeout(350);
    }
    result.samples = samples;
    mkdirSync(config.artifacts, { recursive: true });
    await page.screenshot({ path: join(config.artifacts, 'face-live.png') });
    result.rate = await faceState(page);
    // a caricature preset from the panel; its effect measured on one frame (no tracking update between)
    await page.selectOption('#face-preset', 'big eyes');
    await page.waitForFunction(() => window.kinetreFace.state().weights.some((w) => w !== 0), null, { timeout: 60000 });
    result.caricature = await faceState(page);
    result.morphEffect = await page.evaluate(() => {
      const face = window.kinetreFace.face;
      const weights = [...face.weights];
      face.setMorphs(weights.map(() => 0));
      const plain = window.kinetreFace.state().vertices;
      face.setMorphs(weights);
      return { plain, morphed: window.kinetreFace.state().vertices };
    });
    await page.screenshot({ path: join(config.artifacts, 'face-big-eyes.png') });
    // a face take: record while the face is tracked in 8 more frames, the server exports a GLB
    const recordedFrom = (await faceState(page)).tracked;
    await page.click('#face-record');
    await page.waitForFunction((n) => window.kinetreFace.state().tracked >= n, recordedFrom + 8,
      { timeout: 180000, polling: 250 });
    await page.click('#face-record');
    await page.waitForFunction(() => window.kinetreFace.state().take !== null
      || document.querySelector('#message').className === 'error', null, { timeout: 120000 });
    result.take = (await faceState(page)).take;
    result.message = await page.evaluate(() => document.querySelector('#message').textContent);
    if (result.take) {
      const b64 = await page.evaluate(async (url) => {
        const buf = new Uint8Array(await (await fetch(url)).arrayBuffer());
        let s = '';
        for (let i = 0; i < buf.length; i += 0x8000) s += String.fromCharCode(...buf.subarray(i, i + 0x8000));
        return btoa(s);
      }, result.take.url);
      result.glb = join(config.artifacts, 'face-take.glb');
      writeFileSync(result.glb, Buffer.from(b64, 'base64'));
      result.played = await page.evaluate((url) => window.kinetreFace.play(url, [0, 1, 10, 33, 61, 152, 263, 291]),
        result.take.url);
    }
    if (config.avatar) {
      // an avatar dropped on the page: the face rides on its neck
      await page.setInputFiles('#file', config.avatar);
      await page.waitForFunction(() => window.kinetre.state().avatar.ready, null, { timeout: 120000, polling: 250 });
      // the face placed on the avatar's neck from a frame tracked since
      const ready = (await faceState(page)).tracked;
      await page.waitForFunction((n) => window.kinetreFace.state().anchor === 'avatar'
        && window.kinetreFace.state().tracked >= n, ready + 2, { timeout: 120000, polling: 250 });
      result.onAvatar = await page.evaluate(() => {
        const s = window.kinetreFace.state();
        const at = (j) => {
          const b = window.kinetre.studio.avatars.bone(j);
          b.updateWorldMatrix(true, false);
          return [b.matrixWorld.elements[12], b.matrixWorld.elements[13], b.matrixWorld.elements[14]];
        };
        return { anchor: s.anchor, chin: s.chin, vertices: s.vertices, neck: at('ShoulderCenter'), head: at('Head') };
      });
      await page.screenshot({ path: join(config.artifacts, 'face-on-avatar.png') });
    }
  } finally {
    await browser.close();
  }
}

async function annotate() {
  const { browser, page } = await openPage('/annotate/');
  try {
    await page.waitForFunction(() => window.kinetreAnnotate && window.kinetreAnnotate.ready(), null, { timeout: 60000 });
    const url = `data:image/jpeg;base64,${readFileSync(config.image).toString('base64')}`;
    await page.evaluate(([u, name]) => window.kinetreAnnotate.loadImage(u, name), [url, 'portrait.jpg']);
    await page.evaluate(() => window.kinetreAnnotate.trackFit());
    result.fitted = await page.evaluate(() => window.kinetreAnnotate.save());
    result.fitMessage = await page.evaluate(() => window.kinetreAnnotate.message());
    // the annotator's own adjustments: drag the template 20 px right, widen the jaw
    const box = await page.locator('#view').boundingBox();
    const k = box.width / result.fitted.width;
    const [x, y] = [box.x + result.fitted.annotation.x * k, box.y + result.fitted.annotation.y * k];
    await page.mouse.move(x, y);
    await page.mouse.down();
    await page.mouse.move(x + 20 * k, y, { steps: 4 });
    await page.mouse.up();
    await page.fill('#a-jaw', '0.5');
    await page.dispatchEvent('#a-jaw', 'input');
    result.adjusted = await page.evaluate(() => window.kinetreAnnotate.save());
    await page.check('#flip');
    await mkdirSync(config.artifacts, { recursive: true });
    await page.screenshot({ path: join(config.artifacts, 'annotate-flipped.png') });
    await page.uncheck('#flip');
    await page.screenshot({ path: join(config.artifacts, 'annotate.png') });
    // a chosen pose, saved, then reloaded after the pose was changed: the file restores it
    await page.evaluate((p) => window.kinetreAnnotate.setPose(p), config.pose);
    result.posed = await page.evaluate(() => window.kinetreAnnotate.save());
    await page.evaluate(() => window.kinetreAnnotate.setPose({ yaw: 0, x: 10 }));
    await page.evaluate((text) => window.kinetreAnnotate.loadText(text), JSON.stringify(result.posed));
    result.reloaded = await page.evaluate(() => window.kinetreAnnotate.pose());
    await page.evaluate(() => window.kinetreAnnotate.loadText('{"format": "other"}', 'bad.json'));
    result.badMessage = await page.evaluate(() => window.kinetreAnnotate.message());
  } finally {
    await browser.close();
  }
}

async function rate() {
  // landmarks per second in the page: Face Mesh + Algorithm 2 + the puppet, on the fake camera
  const { browser, page } = await openPage('/?noshadows');
  try {
    await page.waitForFunction(() => window.kinetreFace && window.kinetreFace.face.template !== null, null, { timeout: 60000 });
    await page.keyboard.press('g');
    await page.waitForFunction(() => window.kinetreFace.state().tracked >= 3, null, { timeout: 180000, polling: 250 });
    const first = await faceState(page);
    const start = Date.now();
    await page.waitForTimeout((config.seconds ?? 10) * 1000);
    const last = await faceState(page);
    result.rate = { landmarksPerSecond: (last.tracked + last.lost - first.tracked - first.lost) / ((Date.now() - start) / 1000),
      detectMs: last.detectMs, tracked: last.tracked - first.tracked, lost: last.lost - first.lost };
  } finally {
    await browser.close();
  }
}

const scenarios = { face, annotate, rate };
await report(result, () => scenarios[config.scenario](), { t0 });
