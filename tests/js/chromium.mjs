// Headless Debian Chromium driven by playwright-core, with the flags this machine needs: no
// sandbox (root), no background networking (the network is closed), WebGL through SwiftShader
// (no GPU), a fresh profile. `WAVRAD_CHROMIUM` names the executable.
import { chromium } from 'playwright-core';
import { mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';

/// A persistent context (its first page is `context.pages()[0]`); `options` are playwright's
/// launch options added to these. Closing it removes the profile (again when the script exits,
/// for what Chromium wrote after the close).
export async function launch(options = {}) {
  const userDataDir = mkdtempSync(join(tmpdir(), 'wavrad-chromium-'));
  const context = await chromium.launchPersistentContext(userDataDir, {
    executablePath: process.env.WAVRAD_CHROMIUM || '/usr/bin/chromium',
    headless: true,
    args: [
      '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
      '--disable-background-networking', '--disable-component-update', '--disable-sync',
      '--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    ],
    ...options,
  });
  const remove = () => {
    try {
      rmSync(userDataDir, { recursive: true, force: true, maxRetries: 5, retryDelay: 100 });
    } catch {
      // Chromium may still be writing its profile: a directory left in the system's temporary
      // directory is harmless (the exit handler tries again after a close).
    }
  };
  context.on('close', remove);
  // Chromium can write its profile after the context's close event: try again when the script
  // exits.
  process.once('exit', remove);
  return context;
}
