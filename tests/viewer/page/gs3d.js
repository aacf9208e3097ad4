// three.js + @mkkellogg/gaussian-splats-3d (the viewer issue 54 was filed with), driven frame by
// frame: our own WebGLRenderer and PerspectiveCamera (its projection pinned to the COLMAP
// intrinsics), the viewer's own controls off, the scene shown at once (no fade-in), and a full
// splat sort forced at every camera (the viewer re-sorts on its own only after an 8-degree turn or
// a unit of travel). Switches (options.gs3d): sphericalHarmonicsDegree (the viewer's default 0;
// it knows 0-2), antialiased (false), kernel2DSize (0.3), any other Viewer option as given.
import * as THREE from 'three';
import * as GaussianSplats3D from '@mkkellogg/gaussian-splats-3d';
import { frames } from '/page/harness.js';

export async function create(canvas, options) {
  THREE.ColorManagement.enabled = false;  // the background colour as given, not linearised
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(options.width, options.height, false);
  const [r, g, b] = options.background;
  renderer.setClearColor(new THREE.Color(r, g, b), 1);

  const camera = new THREE.PerspectiveCamera(50, options.width / options.height, 0.01, 1000);
  const projection = new THREE.Matrix4();
  // The viewer calls updateProjectionMatrix on size changes: keep the intrinsics' matrix.
  camera.updateProjectionMatrix = function () {
    this.projectionMatrix.copy(projection);
    this.projectionMatrixInverse.copy(projection).invert();
  };

  const switches = {
    sphericalHarmonicsDegree: 0,
    antialiased: false,
    kernel2DSize: 0.3,
    ...(options.gs3d || {}),
  };
  const viewer = new GaussianSplats3D.Viewer({
    selfDrivenMode: false,
    renderer,
    camera,
    useBuiltInControls: false,
    ignoreDevicePixelRatio: true,
    sharedMemoryForWorkers: self.crossOriginIsolated === true,
    sceneRevealMode: GaussianSplats3D.SceneRevealMode.Instant,
    logLevel: GaussianSplats3D.LogLevel.None,
    ...switches,
  });
  await viewer.addSplatScene(options.model, {
    format: GaussianSplats3D.SceneFormat.Ply,
    showLoadingUI: false,
    progressiveLoad: false,
  });

  // floatTarget (a harness switch, not the viewer's): blend into a half-float target and
  // quantise to 8 bits once, as watergs does, instead of at every blend in the 8-bit canvas.
  const floatTarget = switches.floatTarget === true;
  delete switches.floatTarget;
  let target = null, blit = null;
  if (floatTarget) {
    target = new THREE.WebGLRenderTarget(options.width, options.height, { type: THREE.HalfFloatType });
    const material = new THREE.ShaderMaterial({
      uniforms: { source: { value: target.texture } },
      vertexShader: 'varying vec2 uv0; void main() { uv0 = uv; gl_Position = vec4(position.xy, 0.0, 1.0); }',
      fragmentShader: 'uniform sampler2D source; varying vec2 uv0; void main() { gl_FragColor = texture2D(source, uv0); }',
      depthTest: false, depthWrite: false,
    });
    blit = { scene: new THREE.Scene(), camera: new THREE.OrthographicCamera(-1, 1, 1, -1, 0, 1) };
    blit.scene.add(new THREE.Mesh(new THREE.PlaneGeometry(2, 2), material));
  }

  async function draw() {
    viewer.update();
    if (target) {
      renderer.setRenderTarget(target);
      viewer.render();
      renderer.setRenderTarget(null);
      renderer.render(blit.scene, blit.camera);
    } else {
      viewer.render();
    }
    await frames(2);
  }
  return {
    describe: () => ({ viewer: 'three.js ' + THREE.REVISION + ' + @mkkellogg/gaussian-splats-3d', switches: { ...switches, floatTarget },
                       splats: viewer.getSplatMesh().getSplatCount() }),
    resize(width, height) {
      renderer.setSize(width, height, false);
      if (target) target.setSize(width, height);
    },
    async show(cam) {
      projection.fromArray(cam.projection);
      camera.updateProjectionMatrix();
      camera.position.fromArray(cam.position);
      camera.quaternion.fromArray(cam.quaternion);
      camera.updateMatrixWorld(true);
      viewer.update();  // the splat mesh's uniforms (focal, viewport) for this camera
      await viewer.runSplatSort(true, true);
      if (viewer.sortPromise) await viewer.sortPromise;
      await draw();
    },
    redraw: draw,
  };
}
