// Drives the studio page in Debian's Chromium with playwright-core (no browser download) and prints one
// JSON object with what it measured. Run by tests/e2e/test_studio_page.py:
//   node driver.mjs '{"scenario": "...", "url": "...", "video": "...", "audio": "...", "artifacts": "..."}'
// The fake camera plays a person video (a y4m file), the fake microphone a WAV file, both on a loop.
import { mkdirSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { launchWithCamera, moreTransforms, pageNow, report, shownAfter, state, until, watchTransforms } from './harness.mjs';

const config = JSON.parse(process.argv[2]);
const result = { scenario: config.scenario, steps: [] };
const t0 = Date.now();
const log = (step, extra = {}) => result.steps.push({ step, s: (Date.now() - t0) / 1000, ...extra });

// Chromium refuses fake-capture paths that contain "..": hand it normalised absolute paths.
const launch = (audio) => launchWithCamera(resolve(config.video), audio ? resolve(audio) : null);

async function open(browser, name) {
  const page = await browser.newPage({ viewport: { width: 720, height: 540 }, acceptDownloads: true });
  page.setDefaultTimeout(120000); // SwiftShader on a loaded CI machine: a page busy tracking answers actions slowly
  page.on('pageerror', (e) => log(`${name}: page error`, { message: String(e) }));
  page.on('console', (m) => { if (m.type() === 'error') log(`${name}: console error`, { message: m.text() }); });
  await page.goto(config.url + (config.query ?? ''));
  await page.waitForFunction(() => window.kinetre && window.kinetre.state().meshId !== null, null, { timeout: 60000 });
  await watchTransforms(page);
  return page;
}

function spread(samples) {
  // largest displacement of any sampled vertex between any two samples in time (metres)
  let best = 0;
  for (let a = 0; a < samples.length; a++) {
    for (let b = a + 1; b < samples.length; b++) {
      for (let v = 0; v < samples[a].length; v++) {
        const d = Math.hypot(...samples[a][v].map((x, k) => x - samples[b][v][k]));
        best = Math.max(best, d);
      }
    }
  }
  return best;
}

async function watchVertices(page, seconds, every = 400) {
  const samples = [];
  const end = Date.now() + seconds * 1000;
  while (Date.now() < end) {
    samples.push((await state(page)).vertices);
    await page.waitForTimeout(every);
  }
  return samples;
}

async function startCamera(page, name) {
  await page.keyboard.press('c');
  await until(page, () => window.kinetre.state().trackedJoints >= 12, null, 120000);
  const tracked = (await state(page)).trackedJoints;
  // and the server has this page's frames, so Fit and Possess find a skeleton there
  await until(page, () => window.kinetre.state().users.some((u) => u.client === window.kinetre.state().client && u.frames > 0),
    null, 60000);
  log(`${name}: pose detected`, { tracked });
}

async function possess(page, name, subset = null) {
  await page.bringToFront(); // the other user's page was last in front
  if (subset) await page.selectOption('#subset', subset);
  await page.keyboard.press('f'); // the server takes Fit, then Possess, in the order sent
  await page.keyboard.press('p');
  await until(page, () => window.kinetre.state().possessing || document.querySelector('#message').className === 'error',
    null, 60000);
  const s = await state(page);
  if (!s.possessing) throw new Error(`${name}: possess failed: ${s.message}`);
  log(`${name}: possessing`, { users: s.users });
}

async function screenshot(page, file) {
  mkdirSync(config.artifacts, { recursive: true });
  await page.screenshot({ path: join(config.artifacts, file) });
}

async function single() {
  const browser = await launch(config.audio);
  try {
    const page = await open(browser, 'page');
    const initial = await state(page);
    result.initial = { meshId: initial.meshId, nodeCount: initial.nodeCount, vertices: initial.vertices.length };
    await startCamera(page, 'page');
    await page.keyboard.press('f'); // scale the mesh to the dancer and stand it where she stands
    const attachable = await until(page, () => window.kinetre.state().attachableJoints, null, 30000)
      .catch(() => { log('page: no attachable joint highlighted'); return 0; });
    const rigging = await state(page);
    result.rigging = { attachable, tracked: rigging.trackedJoints };
    await possess(page, 'page');
    await screenshot(page, 'studio-possessed.png');
    // this page's live motion meter: the server's figures for its user, as the status line shows them
    const meter = () => until(page, () => {
      const s = window.kinetre.state();
      const me = s.users.find((u) => u.client === s.client);
      return me?.quality?.jitter != null && me.quality.lag_ms != null
        && { quality: me.quality, cleaning: me.cleaning, status: document.querySelector('#status').textContent };
    }, null, 60000);
    result.meter = [await meter()];
    const moving = await watchVertices(page, 6);
    result.possessedSpread = spread(moving);
    result.meter.push(await meter());
    const during = await state(page);
    result.perf = { fps: during.fps, renderMs: during.renderMs, updateMs: during.updateMs, detectMs: during.detectMs,
      latencyMs: during.latencyMs };

    // record a take while possessed and download it as GLB
    await page.keyboard.press(' ');
    await until(page, () => window.kinetre.state().recording, null, 30000);
    await moreTransforms(page, 15); // poses solved while recording (the take keeps each)
    await page.keyboard.press(' ');
    await page.waitForSelector('#downloads a.download', { timeout: 240000 }); // the take exported
    const [download] = await Promise.all([
      page.waitForEvent('download'),
      page.click('#downloads a:has-text("GLB")'),
    ]);
    const glbPath = join(config.artifacts, 'take.glb');
    await download.saveAs(glbPath);
    result.glb = glbPath;
    result.take = (await state(page)).take;
    result.downloads = await page.$$eval('#downloads a', (links) => links.map((a) => [a.textContent, a.getAttribute('download')]));
    log('take downloaded');

    const released = await pageNow(page);
    await page.keyboard.press('r');
    await until(page, () => !window.kinetre.state().possessing, null, 60000);
    await shownAfter(page, released); // the rest pose the server shows once it let go
    log('released');
    result.releasedSpread = spread(await watchVertices(page, 3));

    // voice: the fake microphone says "possess" on a loop
    if (config.audio) {
      await page.keyboard.press('v');
      await until(page, () => {
        const s = window.kinetre.state();
        return s.possessing && s.voice && s.voice.command && s.voice.command.verb === 'possess';
      }, null, 90000).catch(() => log('voice: no possess heard'));
      const s = await state(page);
      result.voice = { possessing: s.possessing, last: s.voice, utterances: s.voiceUtterances };
      log('voice done');
    }
    await screenshot(page, 'studio-end.png');
    result.final = await state(page);
    delete result.final.vertices;
  } finally {
    await browser.close();
  }
}

async function two() {
  const browser = await launch(null);
  try {
    const a = await open(browser, 'A');
    const b = await open(browser, 'B');
    await startCamera(a, 'A');
    await startCamera(b, 'B');
    await possess(a, 'A', 'left leg');
    await possess(b, 'B', 'right leg');
    await screenshot(a, 'studio-two-users.png');
    const s = await state(a);
    result.users = s.users;
    result.spreadA = spread(await watchVertices(a, 5));
    result.seqB = (await state(b)).transformsSeq;
    result.sameMesh = (await state(a)).meshId === (await state(b)).meshId;
  } finally {
    await browser.close();
  }
}

async function upload() {
  const browser = await launch(null);
  try {
    const page = await open(browser, 'page');
    const before = (await state(page)).meshId;
    await page.setInputFiles('#file', config.bad);
    await until(page, () => document.querySelector('#message').className === 'error', null, 60000);
    result.badMessage = await page.textContent('#message');
    await page.setInputFiles('#file', config.good);
    await until(page, (id) => window.kinetre.state().meshId !== id, before, 120000);
    const s = await state(page);
    result.after = { meshId: s.meshId, meshName: s.meshName, nodeCount: s.nodeCount, before };
    await screenshot(page, 'studio-uploaded.png');
  } finally {
    await browser.close();
  }
}

async function smoke() {
  const browser = await launch(null);
  try {
    const page = await open(browser, 'page');
    await page.waitForTimeout(config.wait ?? 3000);
    result.state = await state(page);
    delete result.state.vertices;
    await screenshot(page, 'studio-smoke.png');
  } finally {
    await browser.close();
  }
}

async function sample() {
  // before any camera: the sample mesh is there and the sample motion moves it
  const browser = await launch(null);
  try {
    const page = await open(browser, 'page');
    await until(page, () => window.kinetre.state().transformsSeen > 3, null, 60000);
    const s = await state(page);
    result.state = { meshName: s.meshName, nodeCount: s.nodeCount, users: s.users, cameraRunning: s.cameraRunning };
    result.spread = spread(await watchVertices(page, 4));
    await screenshot(page, 'studio-sample.png');
  } finally {
    await browser.close();
  }
}

async function perf() {
  // the sample motion drives the mesh; no camera, so the figure is the 3D page alone
  const browser = await launch(null);
  try {
    const page = await open(browser, 'page');
    await page.waitForTimeout(config.wait ?? 10000);
    const s = await state(page);
    result.perf = { fps: s.fps, renderMs: s.renderMs, updateMs: s.updateMs, transformsPerSecond: null,
      latencyMs: s.latencyMs, viewport: '720x540' };
    const seq0 = s.transformsSeen;
    await page.waitForTimeout(5000);
    result.perf.transformsPerSecond = ((await state(page)).transformsSeen - seq0) / 5;
    await screenshot(page, 'studio-perf.png');
  } finally {
    await browser.close();
  }
}

const scenarios = { single, two, upload, smoke, perf, sample };
await report(result, () => scenarios[config.scenario](), { t0, out: config.out });
