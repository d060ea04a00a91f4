// Drives wavrad's dashboard in headless Chromium (playwright-core, Debian's chromium) the way a
// user would, and prints one JSON report on stdout for tests/real_clients/dashboard.rs.
//
// Environment: WAVRAD_BASE (the server, run with --api-token WAVRAD_TOKEN), WAVRAD_CHROMIUM (the
// browser), SCENE_GLTF and SCENE_BIN (a .gltf and its buffer: converges in seconds), SLOW_GLB (a
// scene that never converges), OUT_DIR (downloads' copies and screenshots). DASHBOARD_HTML, when
// set, serves that file as the page instead of the server's (for working on the page without
// rebuilding the server).
import { readFileSync } from "node:fs";
import { launch } from "./chromium.mjs";
import { basename, join } from "node:path";

const env = (name) => {
  const v = process.env[name];
  if (!v) throw new Error(`${name} is not set`);
  return v;
};
const base = env("WAVRAD_BASE");
const token = env("WAVRAD_TOKEN");
const outDir = env("OUT_DIR");
const report = { error: null, page_errors: [] };
const done = (code) => {
  process.stdout.write(JSON.stringify(report) + "\n");
  process.exit(code);
};
setTimeout(() => {
  report.error = "dashboard.mjs timed out after 540 s";
  done(1);
}, 540_000).unref();

const FINAL = ["succeeded", "failed", "cancelled"];
const row = (id) => `tr[data-job="${id}"]`;
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

/// What the page shows for job `id`.
async function rowView(page, id) {
  return page.evaluate((sel) => {
    const tr = document.querySelector(sel);
    if (!tr) return null;
    const badge = tr.querySelector(".badge");
    return {
      state: tr.dataset.state,
      stop_reason: tr.dataset.stopReason || null,
      name: tr.querySelector("td.name strong").textContent,
      badge: badge ? badge.textContent : null,
      badge_color: badge ? getComputedStyle(badge).backgroundColor : null,
      progress: tr.querySelector(".progress-text").textContent,
      progress_bar: tr.querySelector("progress") ? tr.querySelector("progress").value : null,
    };
  }, row(id));
}

/// Watches job `id` on the page until it ends (or `until` says stop); returns the running views
/// seen and the last view.
async function watch(page, id, until = (v) => v && FINAL.includes(v.state), seconds = 300) {
  const runningSeen = [];
  const start = Date.now();
  for (;;) {
    const v = await rowView(page, id);
    if (v && v.state === "running" && !runningSeen.some((s) => s.progress === v.progress)) {
      runningSeen.push(v);
    }
    if (until(v)) return { runningSeen, last: v };
    if (Date.now() - start > seconds * 1000) {
      throw new Error(`job ${id} did not reach the expected state in ${seconds} s: ${JSON.stringify(v)}`);
    }
    await sleep(100);
  }
}

/// Fills the form and submits it; returns the accepted job's id.
async function upload(page, files, parts, fields) {
  await page.setInputFiles("#scene-file", files);
  await page.setInputFiles("#scene-parts", parts);
  await page.selectOption("#order", fields.order || "2");
  await page.fill("#tolerance", fields.tolerance || "");
  await page.fill("#target", fields.target || "");
  await page.fill("#max-seconds", fields.max_seconds || "");
  await page.evaluate(() => { document.getElementById("upload-message").textContent = ""; });
  await page.click("#submit");
  await page.waitForFunction(() => {
    const t = document.getElementById("upload-message").textContent;
    return t.startsWith("accepted") || t.startsWith("refused") || t.startsWith("cannot");
  });
  const text = await page.textContent("#upload-message");
  const id = /job ([0-9a-f]{16})/.exec(text);
  if (!id) throw new Error(`upload not accepted: ${text}`);
  await page.waitForSelector(row(id[1]));
  return id[1];
}

const MAGIC = {
  "lightmap.exr": (b) => b.length > 4 && b.readUInt32LE(0) === 20000630,
  "preview.png": (b) => b.subarray(0, 8).equals(Buffer.from([137, 80, 78, 71, 13, 10, 26, 10])),
  "atlas.png": (b) => b.subarray(0, 8).equals(Buffer.from([137, 80, 78, 71, 13, 10, 26, 10])),
  "scene.glb": (b) => b.subarray(0, 4).toString("latin1") === "glTF",
  result: (b) => { try { return typeof JSON.parse(b.toString("utf8")).stats === "object"; } catch { return false; } },
};

/// Clicks the page's download button for `file` of job `id`: the saved file, or the page's error.
async function download(page, id, file) {
  await page.evaluate(() => { document.getElementById("job-message").textContent = ""; });
  const saved = page.waitForEvent("download", { timeout: 20_000 }).then((d) => ({ d }));
  const failed = page
    .waitForFunction(() => document.getElementById("job-message").textContent.startsWith("download failed"),
      null, { timeout: 20_000 })
    .then(() => ({ d: null }));
  await page.click(`${row(id)} button[data-file="${file}"]`);
  const { d } = await Promise.race([saved, failed]);
  saved.catch(() => {});
  failed.catch(() => {});
  if (!d) return { file, error: await page.textContent("#job-message"), magic_ok: false };
  const path = join(outDir, `download-${basename(d.suggestedFilename())}`);
  await d.saveAs(path);
  const bytes = readFileSync(path);
  return { file, saved_as: d.suggestedFilename(), bytes: bytes.length, magic_ok: MAGIC[file](bytes), error: null };
}

let context = null;
try {
  context = await launch({ acceptDownloads: true, viewport: { width: 1280, height: 900 } });
  if (process.env.DASHBOARD_HTML) {
    const html = readFileSync(process.env.DASHBOARD_HTML);
    await context.route(`${base}/`, (route) =>
      route.fulfill({ status: 200, contentType: "text/html; charset=utf-8", body: html }));
  }
  const page = context.pages()[0] || (await context.newPage());
  page.on("pageerror", (e) => report.page_errors.push(String(e)));
  // Answers the page expects (401 before the token, the refused upload's 422, a missing
  // scene.glb's 404) are logged as "Failed to load resource": only other errors count.
  page.on("console", (m) => {
    if (m.type() === "error" && !m.text().startsWith("Failed to load resource")) report.page_errors.push(m.text());
  });
  await page.goto(`${base}/`);

  // Without the token the page shows the server's 401.
  await page.waitForFunction(() => document.getElementById("status").textContent.length > 0);
  report.without_token = await page.textContent("#status");
  await page.fill("#token", token);
  await page.dispatchEvent("#token", "change");
  await page.waitForFunction(() => /job\(s\)/.test(document.getElementById("status").textContent));

  // A file that is not a scene: the 4xx message is shown.
  await page.setInputFiles("#scene-file", { name: "not_a_scene.glb", mimeType: "model/gltf-binary",
    buffer: Buffer.from("this is not a GLB file") });
  await page.click("#submit");
  await page.waitForFunction(() => document.getElementById("upload-message").textContent.startsWith("refused"));
  report.refused_upload = await page.textContent("#upload-message");

  // The Cornell box, .gltf with its .bin, through the form: progress, then converged.
  const first = await upload(page, env("SCENE_GLTF"), [env("SCENE_BIN")],
    { order: "2", tolerance: "2e-5", target: "0.01" });
  const w1 = await watch(page, first);
  report.first = { id: first, name: w1.last.name, running_views: w1.runningSeen.length,
    running_seen: w1.runningSeen.slice(0, 3).concat(w1.runningSeen.slice(-2)), final: w1.last };

  // Its outputs, downloaded through the page (with the token).
  await page.waitForSelector(`${row(first)} img.preview`, { timeout: 20_000 }).catch(() => {});
  report.downloads = [];
  for (const file of ["result", "lightmap.exr", "preview.png", "atlas.png", "scene.glb"]) {
    report.downloads.push(await download(page, first, file));
  }

  // A scene that never converges: cancelled from the page while it runs.
  const second = await upload(page, env("SLOW_GLB"), [], { order: "1", tolerance: "1e-7" });
  const w2 = await watch(page, second, (v) => v && v.state !== "queued");
  const seenRunning = w2.last.state === "running";
  await page.click(`${row(second)} button.cancel`);
  const w2b = await watch(page, second);
  report.cancelled = { id: second, seen_running: seenRunning, final: w2b.last };

  // The same with a one-second time budget: it stops on the budget and says so.
  const third = await upload(page, env("SLOW_GLB"), [], { order: "1", max_seconds: "1" });
  const w3 = await watch(page, third);
  report.time_budget = { id: third, final: w3.last };

  await page.screenshot({ path: join(outDir, "dashboard-desktop.png"), fullPage: true });

  // A phone's width: no horizontal scrolling, the converged job's outputs on screen.
  const phone = await context.newPage();
  phone.on("pageerror", (e) => report.page_errors.push(String(e)));
  await phone.setViewportSize({ width: 390, height: 844 });
  await phone.goto(`${base}/`);
  await phone.waitForSelector(`${row(first)} img.preview`, { timeout: 20_000 });
  report.phone = await phone.evaluate((sel) => {
    const out = document.querySelector(sel + " .outputs");
    const shown = [...out.children, document.querySelector(sel + " img.preview")];
    const inside = shown.every((c) => {
      const r = c.getBoundingClientRect();
      return r.width > 0 && r.left >= 0 && r.right <= document.documentElement.clientWidth;
    });
    return {
      scroll_width: document.documentElement.scrollWidth,
      client_width: document.documentElement.clientWidth,
      outputs_inside: inside,
    };
  }, row(first));
  report.phone.outputs_visible = await phone.locator(`${row(first)} .outputs button[data-file="lightmap.exr"]`).isVisible();
  await phone.locator(`${row(first)} .outputs`).scrollIntoViewIfNeeded();
  await phone.screenshot({ path: join(outDir, "dashboard-phone.png"), fullPage: true });
  await context.close();
  done(0);
} catch (e) {
  report.error = String((e && e.stack) || e);
  if (context) await context.close().catch(() => {});
  done(1);
}
