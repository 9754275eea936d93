// Opens the viewer (web/) in Debian's headless Chromium and saves what its canvas shows, for tests/tools/test_viewer.cpp.
// No browser download and no driver package: Chromium is driven over its DevTools protocol on a pipe
// (--remote-debugging-pipe: commands on fd 3, replies on fd 4, NUL-separated JSON), and the files are served on
// 127.0.0.1 by web/serve.mjs.
//
// usage: node viewer_capture.mjs CHROMIUM DATA_DIR QUERY OUT_PREFIX [WEB_ROOT [WINDOW]]
//   writes OUT_PREFIX.rgba (the canvas: RGBA8, rows top to bottom), OUT_PREFIX.png and OUT_PREFIX.json
//   ({width, height, camera: {position, fov}}: the canvas's drawing buffer and the camera it was rendered from);
//   exit 1 with one line on stderr when the page reports an error or is not ready within 45 s.
//   WINDOW (WxH): once the page is ready, the window's viewport is resized to W x H CSS pixels (as a user resizing
//   the window would), and after two animation frames the canvas is captured, and so is the whole viewport as the
//   browser shows it: OUT_PREFIX.window.rgba (RGBA8, rows top to bottom) and window_width, window_height in the
//   JSON.
import { spawn } from 'node:child_process';
import { mkdtempSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, resolve } from 'node:path';
import { serve, webRoot } from '../../web/serve.mjs';

const [chromiumPath, dataDir, query, outPrefix, root, windowSize] = process.argv.slice(2);
const window_ = windowSize ? windowSize.split('x').map(Number) : null;
if (!outPrefix || (window_ && (window_.length !== 2 || !window_.every((v) => Number.isInteger(v) && v > 0)))) {
  console.error('usage: node viewer_capture.mjs CHROMIUM DATA_DIR QUERY OUT_PREFIX [WEB_ROOT [WxH]]');
  process.exit(2);
}
const deadline = Date.now() + 45000;
const profile = mkdtempSync(join(tmpdir(), 'envkit-viewer-chromium-'));
const { server, url } = await serve(dataDir, 0, root ? resolve(root) : webRoot);

const browser = spawn(
  chromiumPath,
  [
    '--headless',
    '--no-sandbox', // CI runs as root, where Chromium's sandbox refuses to start
    '--remote-debugging-pipe',
    // WebGL on the CPU: SwiftShader through ANGLE, whatever GPU the machine has (none on CI).
    '--use-angle=swiftshader',
    '--enable-unsafe-swiftshader',
    '--ignore-gpu-blocklist',
    '--no-first-run',
    '--no-default-browser-check',
    '--disable-extensions',
    '--disable-background-networking',
    '--force-device-scale-factor=1',
    `--user-data-dir=${profile}`,
    'about:blank',
  ],
  { stdio: ['ignore', 'ignore', 'pipe', 'pipe', 'pipe'] },
);
let stderr = '';
browser.stdio[2].on('data', (d) => {
  stderr += d;
});

let nextId = 1;
const pending = new Map();
let buffer = Buffer.alloc(0);
browser.stdio[4].on('data', (chunk) => {
  buffer = Buffer.concat([buffer, chunk]);
  for (let end = buffer.indexOf(0); end >= 0; end = buffer.indexOf(0)) {
    const message = JSON.parse(buffer.subarray(0, end).toString('utf8'));
    buffer = buffer.subarray(end + 1);
    // The page's console errors and warnings (shader compile logs, failed loads) go to stderr.
    if (message.method === 'Runtime.consoleAPICalled' && ['error', 'warning'].includes(message.params.type)) {
      console.error(`page ${message.params.type}: ${message.params.args.map((a) => a.value ?? a.description).join(' ')}`);
    } else if (message.method === 'Runtime.exceptionThrown') {
      console.error(`page exception: ${message.params.exceptionDetails.exception?.description ?? ''}`);
    }
    const waiter = message.id !== undefined && pending.get(message.id);
    if (waiter) {
      pending.delete(message.id);
      if (message.error) waiter.fail(new Error(`${waiter.method}: ${message.error.message}`));
      else waiter.ok(message.result);
    }
  }
});

function send(method, params = {}, sessionId = undefined) {
  const id = nextId++;
  const message = { id, method, params };
  if (sessionId) message.sessionId = sessionId;
  browser.stdio[3].write(JSON.stringify(message) + '\0');
  return new Promise((ok, fail) => pending.set(id, { ok, fail, method }));
}

const sleep = (ms) => new Promise((ok) => setTimeout(ok, ms));

async function evaluate(expression, sessionId) {
  const r = await send('Runtime.evaluate', { expression, returnByValue: true, awaitPromise: true }, sessionId);
  if (r.exceptionDetails) throw new Error(`page: ${r.exceptionDetails.exception?.description ?? r.exceptionDetails.text}`);
  return r.result.value;
}

let code = 0;
try {
  const { targetId } = await send('Target.createTarget', { url: 'about:blank' });
  const { sessionId } = await send('Target.attachToTarget', { targetId, flatten: true });
  await send('Page.enable', {}, sessionId);
  await send('Runtime.enable', {}, sessionId);
  await send('Page.navigate', { url: `${url}index.html?${query}` }, sessionId);
  let state;
  for (;;) {
    state = await evaluate('window.envkitViewer ? [window.envkitViewer.state, window.envkitViewer.message] : null', sessionId);
    if (state && state[0] !== 'loading') break;
    if (Date.now() > deadline) throw new Error('the viewer did not finish loading within 45 s');
    await sleep(100);
  }
  if (state[0] !== 'ready') throw new Error(`the viewer reports: ${state[1]}`);
  const frames = 'new Promise((ok) => requestAnimationFrame(() => requestAnimationFrame(() => ok(true))))';
  if (window_) {
    const [width, height] = window_;
    await send('Emulation.setDeviceMetricsOverride', { width, height, deviceScaleFactor: 1, mobile: false }, sessionId);
    await evaluate(frames, sessionId);
  }
  const shot = await evaluate('window.envkitViewer.capture()', sessionId);
  writeFileSync(`${outPrefix}.rgba`, Buffer.from(shot.rgba, 'base64'));
  writeFileSync(`${outPrefix}.png`, Buffer.from(shot.png.replace(/^data:image\/png;base64,/, ''), 'base64'));
  const info = { width: shot.width, height: shot.height, camera: shot.camera };
  if (window_) {
    // The viewport as the browser composites it, decoded by the browser itself (no PNG decoder here).
    const { data } = await send('Page.captureScreenshot', { format: 'png' }, sessionId);
    const pixels = await evaluate(
      `(async () => {
        const image = await createImageBitmap(await (await fetch('data:image/png;base64,${data}')).blob());
        const c = new OffscreenCanvas(image.width, image.height).getContext('2d');
        c.drawImage(image, 0, 0);
        const rgba = c.getImageData(0, 0, image.width, image.height).data;
        let binary = '';
        for (let i = 0; i < rgba.length; i += 0x8000) binary += String.fromCharCode(...rgba.subarray(i, i + 0x8000));
        return { width: image.width, height: image.height, rgba: btoa(binary) };
      })()`,
      sessionId,
    );
    writeFileSync(`${outPrefix}.window.rgba`, Buffer.from(pixels.rgba, 'base64'));
    info.window_width = pixels.width;
    info.window_height = pixels.height;
  }
  writeFileSync(`${outPrefix}.json`, JSON.stringify(info));
  await send('Browser.close').catch(() => {});
} catch (e) {
  const hint = stderr.split('\n').find((l) => /error/i.test(l)) ?? '';
  console.error(`viewer_capture: ${e.message}${hint ? ` (chromium: ${hint.trim()})` : ''}`);
  code = 1;
}
// Let the browser finish writing its profile before it is removed (it is also asked to close after an error); kill
// it if it does not exit, and wait for that too.
const exited = new Promise((ok) => browser.once('exit', ok));
if (code !== 0) send('Browser.close').catch(() => {});
if (browser.exitCode === null) await Promise.race([exited, sleep(5000)]);
if (browser.exitCode === null && browser.signalCode === null) {
  browser.kill('SIGKILL');
  await Promise.race([exited, sleep(5000)]);
}
server.close();
try {
  rmSync(profile, { recursive: true, force: true, maxRetries: 10, retryDelay: 100 });
} catch (e) {
  console.error(`viewer_capture: could not remove ${profile}: ${e.message}`);
}
process.exit(code);
