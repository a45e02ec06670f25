// The studio page behind a gateway studio whose scene runs in another process, in Debian's
// Chromium: the page says "scene lost" when the scene process dies and recovers when a new one starts.
//   node driver_network.mjs '{"url": "http://127.0.0.1:PORT/?token=…", "artifacts": "…"}'
// Prints "READY" once the page shows the mesh (the test then kills the scene), "LOST" once the page
// says so (the test starts a new scene), and finally one JSON object with what it saw.
import { mkdirSync } from 'node:fs';
import { join } from 'node:path';
import { chromium, report } from './harness.mjs';

const config = JSON.parse(process.argv[2]);
const result = { scenario: 'scene-lost' };
const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium', headless: true,
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-background-networking',
    '--disable-background-timer-throttling', '--disable-renderer-backgrounding'],
});
const statusOf = (page) => page.evaluate(() => ({
  status: document.getElementById('status').textContent,
  message: window.kinetre.state().message,
  meshId: window.kinetre.state().meshId,
}));
await report(result, async () => {
  const page = await browser.newPage({ viewport: { width: 480, height: 360 } });
  await page.goto(config.url);
  await page.waitForFunction(() => window.kinetre && window.kinetre.state().meshId !== null, null, { timeout: 60000 });
  result.before = await statusOf(page);
  process.stdout.write('READY\n');
  await page.waitForFunction(() => document.getElementById('status').textContent.includes('scene lost'), null,
    { timeout: 30000, polling: 100 });
  result.lost = await statusOf(page);
  mkdirSync(config.artifacts, { recursive: true });
  await page.screenshot({ path: join(config.artifacts, 'studio-scene-lost.png') });
  process.stdout.write('LOST\n');
  await page.waitForFunction(() => !document.getElementById('status').textContent.includes('scene lost')
    && window.kinetre.state().message.includes('the scene is back'), null, { timeout: 90000, polling: 100 });
  result.after = await statusOf(page);
}, { cleanup: () => browser.close() });
