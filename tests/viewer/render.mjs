#!/usr/bin/env node
// Renders a 3DGS PLY at COLMAP cameras in a real web viewer in headless Chromium (WebGL2 on
// SwiftShader) and saves each frame as a PNG screenshot: the leak a viewer's user makes.
//   node render.mjs --viewer gs3d|playcanvas --model MODEL.ply --cameras cameras.json
//                   --output DIR [--background r,g,b|black|white] [--set KEY=JSON ...]
//                   [--chromium /usr/bin/chromium] [--max_draws 12]
// cameras.json: Inria's list (img_name, width, height, position = camera centre, rotation =
// camera-to-world rows, fx, fy) with cx, cy (pixels, COLMAP convention), as
// `watergs render --output_path DIR` writes beside its PNGs (DIR/cameras.json). COLMAP cameras
// look down +z with y down; three.js and PlayCanvas cameras look down -z with y up, so the
// viewer's camera is the COLMAP one turned 180 degrees about its x axis, and its projection matrix
// maps pixel u = fx x/z + cx to NDC 2u/W - 1 (and v to 1 - 2v/H) exactly, principal point
// included. --set passes a viewer switch (gs3d: a Viewer option such as
// sphericalHarmonicsDegree=2; playcanvas: unified=false or an app.scene.gsplat parameter such as
// minPixelSize=0). Each camera is drawn until three screenshots in a row, 0.1 s apart, are
// identical (a viewer that sorts in a worker has caught up; at most --max_draws). Writes DIR/<img_name>.png and
// DIR/viewer.json (the viewer, its switches, seconds per frame, draws per camera).
// Exit 2 on a usage error, 1 when a page or the browser fails.
import { createServer } from 'node:http';
import { mkdirSync, readFileSync, statSync, createReadStream, writeFileSync } from 'node:fs';
import { dirname, extname, join, resolve, sep } from 'node:path';
import { fileURLToPath } from 'node:url';
import puppeteer from 'puppeteer-core';

const here = dirname(fileURLToPath(import.meta.url));

function usage(message) {
  console.error(`render.mjs: ${message}`);
  console.error('usage: node render.mjs --viewer gs3d|playcanvas --model MODEL.ply --cameras cameras.json ' +
                '--output DIR [--background r,g,b] [--set KEY=JSON ...] [--chromium PATH] [--max_draws N]');
  process.exit(2);
}

function parseArgs(argv) {
  const args = { background: '0,0,0', set: [], chromium: process.env.CHROMIUM || '/usr/bin/chromium',
                 max_draws: '12' };
  for (let i = 0; i < argv.length; ++i) {
    const key = argv[i].replace(/^--/, '');
    if (!argv[i].startsWith('--') || i + 1 >= argv.length) usage(`bad argument '${argv[i]}'`);
    const value = argv[++i];
    if (key === 'set') args.set.push(value);
    else if (['viewer', 'model', 'cameras', 'output', 'background', 'chromium', 'max_draws'].includes(key)) {
      args[key] = value;
    } else usage(`unknown option --${key}`);
  }
  for (const key of ['viewer', 'model', 'cameras', 'output']) if (!args[key]) usage(`--${key} is required`);
  if (!['gs3d', 'playcanvas'].includes(args.viewer)) usage(`--viewer must be gs3d or playcanvas`);
  return args;
}

export function parseBackground(text) {
  if (text === 'black') return [0, 0, 0];
  if (text === 'white') return [1, 1, 1];
  const parts = text.split(',').map(Number);
  if (parts.length !== 3 || parts.some((v) => !(v >= 0 && v <= 1))) {
    throw new Error(`--background must be r,g,b in [0, 1], black or white, got '${text}'`);
  }
  return parts;
}

// Rotation matrix (rows) to a quaternion [x, y, z, w].
function quaternionOf(m) {
  const [[m00, m01, m02], [m10, m11, m12], [m20, m21, m22]] = m;
  const trace = m00 + m11 + m22;
  let x, y, z, w;
  if (trace > 0) {
    const s = 0.5 / Math.sqrt(trace + 1);
    w = 0.25 / s; x = (m21 - m12) * s; y = (m02 - m20) * s; z = (m10 - m01) * s;
  } else if (m00 > m11 && m00 > m22) {
    const s = 2 * Math.sqrt(1 + m00 - m11 - m22);
    w = (m21 - m12) / s; x = 0.25 * s; y = (m01 + m10) / s; z = (m02 + m20) / s;
  } else if (m11 > m22) {
    const s = 2 * Math.sqrt(1 + m11 - m00 - m22);
    w = (m02 - m20) / s; x = (m01 + m10) / s; y = 0.25 * s; z = (m12 + m21) / s;
  } else {
    const s = 2 * Math.sqrt(1 + m22 - m00 - m11);
    w = (m10 - m01) / s; x = (m02 + m20) / s; y = (m12 + m21) / s; z = 0.25 * s;
  }
  return [x, y, z, w];
}

// One Inria camera (with cx, cy) to the viewer's: position, orientation of a -z-looking, y-up
// camera, and an OpenGL projection (column-major) with the exact pinhole intrinsics.
export function viewerCamera(cam, near = 0.01, far = 1000) {
  const { width: W, height: H, fx, fy } = cam;
  const cx = cam.cx ?? W / 2, cy = cam.cy ?? H / 2;
  // Camera-to-world columns are COLMAP's x (right), y (down), z (forward); flip y and z.
  const R = cam.rotation;
  const m = R.map((row) => [row[0], -row[1], -row[2]]);
  const rows = [
    [2 * fx / W, 0, 1 - 2 * cx / W, 0],
    [0, 2 * fy / H, 2 * cy / H - 1, 0],
    [0, 0, -(far + near) / (far - near), -2 * far * near / (far - near)],
    [0, 0, -1, 0],
  ];
  const projection = [];
  for (let c = 0; c < 4; ++c) for (let r = 0; r < 4; ++r) projection.push(rows[r][c]);
  return { name: cam.img_name, width: W, height: H, position: cam.position, quaternion: quaternionOf(m),
           projection };
}

const types = { '.html': 'text/html', '.js': 'text/javascript', '.mjs': 'text/javascript',
                '.json': 'application/json', '.wasm': 'application/wasm', '.map': 'application/json' };

// Serves the harness folder (page/, node_modules/) and the model at /model<ext>, cross-origin
// isolated (the gs3d viewer's sort worker shares memory when it is).
function serve(modelPath) {
  const server = createServer((req, res) => {
    const path = decodeURIComponent(new URL(req.url, 'http://localhost').pathname);
    let file = null;
    if (path === '/model' + extname(modelPath)) file = modelPath;
    else {
      const candidate = resolve(here, '.' + path);
      if (candidate.startsWith(here + sep)) file = candidate;
    }
    let size = -1;
    try { size = file ? statSync(file).isFile() ? statSync(file).size : -1 : -1; } catch { size = -1; }
    if (size < 0) {
      res.writeHead(404);
      res.end();
      return;
    }
    res.writeHead(200, {
      'Content-Type': types[extname(file)] || 'application/octet-stream',
      'Content-Length': size,
      'Cross-Origin-Opener-Policy': 'same-origin',
      'Cross-Origin-Embedder-Policy': 'require-corp',
      'Cache-Control': 'no-store',
    });
    createReadStream(file).pipe(res);
  });
  return new Promise((ok) => server.listen(0, '127.0.0.1', () => ok(server)));
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  let background;
  try { background = parseBackground(args.background); } catch (e) { usage(e.message); }
  const switches = {};
  for (const item of args.set) {
    const at = item.indexOf('=');
    if (at <= 0) usage(`--set wants KEY=JSON, got '${item}'`);
    const raw = item.slice(at + 1);
    let value;
    try { value = JSON.parse(raw); } catch { value = raw; }
    switches[item.slice(0, at)] = value;
  }
  const cameras = JSON.parse(readFileSync(args.cameras, 'utf8')).map((c) => viewerCamera(c));
  if (cameras.length === 0) usage(`${args.cameras} lists no cameras`);
  const maxDraws = Number(args.max_draws);
  mkdirSync(args.output, { recursive: true });

  const server = await serve(resolve(args.model));
  const base = `http://127.0.0.1:${server.address().port}`;
  const browser = await puppeteer.launch({
    executablePath: args.chromium,
    headless: true,
    args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
           '--disable-dev-shm-usage', '--hide-scrollbars', '--force-device-scale-factor=1',
           '--force-color-profile=srgb'],
  });
  const errors = [];
  try {
    const page = await browser.newPage();
    page.on('pageerror', (e) => errors.push(`page error: ${e.message}`));
    page.on('console', (m) => { if (m.type() === 'error') errors.push(`console: ${m.text()}`); });
    page.setDefaultTimeout(600000);
    const { width, height } = cameras[0];
    await page.setViewport({ width, height, deviceScaleFactor: 1 });
    await page.goto(`${base}/page/index.html?viewer=${args.viewer}`, { waitUntil: 'load' });
    await page.waitForFunction(() => window.harnessReady === true);
    const start = Date.now();
    const description = await page.evaluate((o) => window.harness.init(o), {
      model: '/model' + extname(args.model), background, width, height, [args.viewer]: switches,
    }).catch((e) => { throw new Error(`${e.message}\n${errors.join('\n')}`); });
    const loadSeconds = (Date.now() - start) / 1000;
    // Another camera (the last) once before the real ones: a viewer that builds its buffers on
    // the first frames has done so before any screenshot is kept. Not the first camera itself:
    // PlayCanvas 2.23.3's unified renderer, shown the same camera twice in a row, kept drawing a
    // stale view of it (11 dB against watergs' render instead of 23).
    if (cameras.length > 1) {
      await page.evaluate((c) => window.harness.show(c), cameras[cameras.length - 1]);
      await page.evaluate(() => window.harness.redraw());
    }
    const frames = [];
    for (const cam of cameras) {
      const t0 = Date.now();
      if (cam.width !== page.viewport().width || cam.height !== page.viewport().height) {
        await page.setViewport({ width: cam.width, height: cam.height, deviceScaleFactor: 1 });
      }
      await page.evaluate((c) => window.harness.show(c), cam);
      const clip = { x: 0, y: 0, width: cam.width, height: cam.height };
      let shot = await page.screenshot({ type: 'png', clip });
      let draws = 1, same = 0;
      while (draws < maxDraws && same < 2) {
        await new Promise((ok) => setTimeout(ok, 100));
        await page.evaluate(() => window.harness.redraw());
        const next = await page.screenshot({ type: 'png', clip });
        ++draws;
        same = Buffer.compare(next, shot) === 0 ? same + 1 : 0;
        shot = next;
      }
      const settled = same >= 2;
      writeFileSync(join(args.output, `${cam.name}.png`), shot);
      frames.push({ name: cam.name, width: cam.width, height: cam.height, draws, settled,
                    seconds: (Date.now() - t0) / 1000 });
      if (!settled) console.error(`render.mjs: ${cam.name}: still changing after ${draws} draws`);
    }
    if (errors.length) console.error(errors.join('\n'));
    const report = { ...description, chromium: await browser.version(), background, model: resolve(args.model),
                     cameras: resolve(args.cameras), load_seconds: loadSeconds, frames, page_errors: errors };
    writeFileSync(join(args.output, 'viewer.json'), JSON.stringify(report, null, 2) + '\n');
    console.log(`render.mjs: ${args.viewer}: ${frames.length} frames -> ${args.output} ` +
                `(load ${loadSeconds.toFixed(1)} s, ${(frames.reduce((s, f) => s + f.seconds, 0) / frames.length)
                  .toFixed(2)} s a frame)`);
  } finally {
    await browser.close();
    server.close();
  }
}

if (process.argv[1] && resolve(process.argv[1]) === fileURLToPath(import.meta.url)) {
  main().catch((e) => {
    console.error(`render.mjs: ${e.stack || e.message}`);
    process.exit(1);
  });
}
