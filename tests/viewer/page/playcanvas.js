// The PlayCanvas engine (the lineage of SuperSplat and splat-transform), loading the PLY as a gsplat
// asset, with its defaults unless switched (options.playcanvas): `unified` (the gsplat
// component's, default true) and any of the scene's gsplat parameters (app.scene.gsplat:
// antiAlias, minPixelSize, alphaClip, dataFormat 'compact' | 'large', radialSorting, ...).
// The camera's projection is the COLMAP intrinsics' (calculateProjection), no tone mapping.
import * as pc from 'playcanvas';
import { frames } from '/page/harness.js';

export async function create(canvas, options) {
  const app = new pc.Application(canvas, {
    graphicsDeviceOptions: {
      antialias: false,
      alpha: false,
      preserveDrawingBuffer: true,
      deviceTypes: [pc.DEVICETYPE_WEBGL2],
    },
  });
  app.setCanvasFillMode(pc.FILLMODE_NONE);
  app.setCanvasResolution(pc.RESOLUTION_FIXED, options.width, options.height);
  app.start();

  const { unified = true, ...sceneParams } = options.playcanvas || {};
  for (const [key, value] of Object.entries(sceneParams)) app.scene.gsplat[key] = value;

  const projection = new pc.Mat4();
  const cameraEntity = new pc.Entity('camera');
  const [r, g, b] = options.background;
  cameraEntity.addComponent('camera', {
    clearColor: new pc.Color(r, g, b, 1),
    nearClip: 0.01,
    farClip: 1000,
    toneMapping: pc.TONEMAP_NONE,
    gammaCorrection: pc.GAMMA_SRGB,
  });
  cameraEntity.camera.calculateProjection = (mat) => mat.copy(projection);
  app.root.addChild(cameraEntity);

  const asset = new pc.Asset('model', 'gsplat', { url: options.model });
  app.assets.add(asset);
  await new Promise((resolve, reject) => {
    asset.once('load', resolve);
    asset.once('error', (err) => reject(new Error(`loading ${options.model}: ${err}`)));
    app.assets.load(asset);
  });
  const splat = new pc.Entity('splat');
  splat.addComponent('gsplat', { asset, unified });
  app.root.addChild(splat);
  await frames(3);

  return {
    describe: () => ({ viewer: 'playcanvas ' + pc.version, switches: { unified, ...sceneParams },
                       splats: asset.resource?.gsplatData?.numSplats ?? null }),
    resize(width, height) {
      app.setCanvasResolution(pc.RESOLUTION_FIXED, width, height);
    },
    async show(cam) {
      projection.set(cam.projection);
      cameraEntity.setPosition(cam.position[0], cam.position[1], cam.position[2]);
      const [x, y, z, w] = cam.quaternion;
      cameraEntity.setRotation(new pc.Quat(x, y, z, w));
      await frames(3);
    },
    redraw: () => frames(2),
  };
}
