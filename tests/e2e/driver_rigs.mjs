// The studio's joint-map entry in Debian's Chromium (playwright-core): upload a map through the panel's file
// input, read what the page and the server then show, clear it. Prints one JSON object.
//   node driver_rigs.mjs '{"url": "...", "map": "path/to/map.json", "bad": "path/to/bad.json", "artifacts": "..."}'
import { mkdirSync } from 'node:fs';
import { join } from 'node:path';
import { chromium, report } from './harness.mjs';

const config = JSON.parse(process.argv[2]);
const result = { ok: false, errors: [] };
const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium', headless: true, args: ['--headless', '--no-sandbox', '--disable-gpu'],
});
await report(result, async () => {
  const page = await browser.newPage({ viewport: { width: 720, height: 540 } });
  page.on('pageerror', (e) => result.errors.push(String(e)));
  await page.goto(config.url + '/?noshadows');
  await page.waitForSelector('#joint-map-row', { timeout: 60000 });
  const label = () => page.locator('#joint-map-name').textContent();
  const server = () => page.evaluate(() => fetch('api/state').then((r) => r.json()).then((s) => s.joint_map));

  await page.setInputFiles('#joint-map', config.bad);
  await page.waitForFunction(() => document.querySelector('#message').classList.contains('error'), null,
    { timeout: 30000 });
  result.badMessage = await page.locator('#message').textContent();

  await page.setInputFiles('#joint-map', config.map);
  await page.waitForFunction(() => document.querySelector('#joint-map-name').textContent !== '', null,
    { timeout: 30000 });
  result.shown = await label();
  result.server = await server();
  result.clearVisible = await page.locator('#joint-map-clear').isVisible();
  mkdirSync(config.artifacts, { recursive: true });
  await page.screenshot({ path: join(config.artifacts, 'joint-map.png') });

  await page.click('#joint-map-clear');
  await page.waitForFunction(() => document.querySelector('#joint-map-name').textContent === '', null,
    { timeout: 30000 });
  result.afterClear = await server();
}, { cleanup: () => browser.close() });
