// In-page side of the harness: loads one viewer (?viewer=gs3d or playcanvas) and
// exposes window.harness for render.mjs (puppeteer):
//   await harness.init(options)  loads the model; options: {model (URL), background [r,g,b],
//                                width, height, viewer-specific switches}
//   await harness.show(camera)   puts the viewer's camera at {width, height, position,
//                                quaternion [x,y,z,w], projection (16, column-major)} and draws
//   await harness.redraw()       draws again (a viewer that sorts in a worker catches up)
// Each viewer module exports create(canvas, options) -> {resize(w, h), show(camera), redraw()}.
const viewers = {
  gs3d: () => import('/page/gs3d.js'),
  playcanvas: () => import('/page/playcanvas.js'),
};

const params = new URLSearchParams(location.search);
const name = params.get('viewer');
let instance = null;
let size = [0, 0];

function resizeCanvas(canvas, width, height) {
  canvas.width = width;
  canvas.height = height;
  canvas.style.width = `${width}px`;
  canvas.style.height = `${height}px`;
}

window.harness = {
  async init(options) {
    if (!viewers[name]) throw new Error(`unknown viewer '${name}' (gs3d, playcanvas)`);
    const canvas = document.getElementById('view');
    const [r, g, b] = options.background;
    document.body.style.background = `rgb(${r * 255}, ${g * 255}, ${b * 255})`;
    resizeCanvas(canvas, options.width, options.height);
    size = [options.width, options.height];
    const module = await viewers[name]();
    instance = await module.create(canvas, options);
    return instance.describe();
  },
  async show(camera) {
    if (camera.width !== size[0] || camera.height !== size[1]) {
      resizeCanvas(document.getElementById('view'), camera.width, camera.height);
      instance.resize(camera.width, camera.height);
      size = [camera.width, camera.height];
    }
    await instance.show(camera);
  },
  async redraw() {
    await instance.redraw();
  },
};

// Resolves after the next n animation frames (the browser has composited what was drawn).
export function frames(n) {
  return new Promise((resolve) => {
    const step = () => (--n <= 0 ? resolve() : requestAnimationFrame(step));
    requestAnimationFrame(step);
  });
}
window.harnessReady = true;
