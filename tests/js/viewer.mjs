// Opens wavrad's dashboard in headless Chromium, follows a finished job's "3-D view" link, waits
// for the bake to render, and prints one JSON line: the exposure, the page's errors, and the canvas pixels at a grid of
// points with the surface point and normal under each (from the page's `wavradView.sample`).
// Usage: node viewer.mjs BASE_URL JOB_ID [TOKEN] [SCREENSHOT.png]
import { launch } from './chromium.mjs';

const [base, job, token, screenshot] = process.argv.slice(2);
const context = await launch();
const errors = [];
try {
  const page = context.pages()[0] || (await context.newPage());
  page.on('pageerror', (e) => errors.push(String(e)));
  // Answers the pages expect (the dashboard's 404 for a file not written) are logged as
  // "Failed to load resource": only other errors count.
  page.on('console', (m) => {
    if (m.type() === 'error' && !m.text().startsWith('Failed to load resource')) errors.push(m.text());
  });
  await page.setViewportSize({ width: 480, height: 360 });
  await page.goto(base + '/');
  if (token) await page.evaluate((t) => localStorage.setItem('wavrad-token', t), token);
  // From the dashboard's job list, as a user gets there.
  await page.reload();
  const link = page.locator(`a.view3d[href="/view?job=${job}"]`);
  await link.waitFor({ timeout: 30000 });
  await link.click();
  await page.waitForURL(`**/view?job=${job}`);
  await page.waitForFunction(() => window.wavradView && (window.wavradView.ready || window.wavradView.error), null, { timeout: 60000 });
  const state = await page.evaluate(() => ({ error: window.wavradView.error, lightmapped: window.wavradView.lightmappedMaterials }));
  let samples = [];
  let exposure = null;
  if (!state.error) {
    const size = await page.evaluate(() => [document.getElementById('view').width, document.getElementById('view').height]);
    const points = [];
    for (let j = 1; j < 12; j++) for (let i = 1; i < 16; i++) points.push([(i * size[0]) / 16, (j * size[1]) / 12]);
    samples = await page.evaluate((p) => window.wavradView.sample(p), points);
    exposure = await page.evaluate(() => window.wavradView.exposureNow());
    if (screenshot) await page.screenshot({ path: screenshot });
  }
  console.log(JSON.stringify({ error: state.error, lightmapped: state.lightmapped, exposure, errors, samples }));
} finally {
  await context.close();
}
