"""The objects of the Python module: a COLMAP workspace (views, cameras,
images), cameras made from numpy arrays, models made from arrays, saved,
loaded and rendered."""

import numpy as np
import pytest

import watergs
from conftest import DOWNSCALE, SCENE


def test_workspace():
    workspace = watergs.Workspace(SCENE, downscale=DOWNSCALE)
    assert len(workspace) == 48
    assert workspace.names == sorted(workspace.names)
    assert workspace.has_images
    test, train = workspace.test_views(), workspace.train_views()
    assert test == list(range(0, 48, 8))
    assert sorted(test + train) == list(range(48))
    assert workspace.train_views(eval=False) == list(range(48))
    camera = workspace.camera(3)
    assert (camera.width, camera.height) == (60, 45)
    # R is a rotation and the centre is -R^T t.
    assert np.allclose(camera.R @ camera.R.T, np.eye(3), atol=1e-9)
    assert np.allclose(camera.center, -camera.R.T @ camera.t)
    image = workspace.image(3)
    assert image.shape == (45, 60, 3) and image.dtype == np.float32
    assert 0 <= image.min() and image.max() <= 1 and image.std() > 0.01
    full = watergs.Workspace(SCENE)
    assert full.camera(3).width == 480
    assert full.camera(3).fx == pytest.approx(8 * camera.fx)


def test_camera_from_arrays():
    rotation = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], dtype=np.float32)
    camera = watergs.Camera(64, 48, 50.0, 51.0, R=rotation, t=[1, 2, 3])
    assert (camera.cx, camera.cy) == (32.0, 24.0)
    assert np.array_equal(camera.R, rotation)
    assert camera.t.tolist() == [1, 2, 3]
    assert np.allclose(camera.center, -rotation.T @ [1, 2, 3])


def one_gaussian(colour_dc, sh_rest=None):
    return watergs.Model.from_arrays(
        means=[[0.0, 0.0, 0.0]], log_scales=[[np.log(0.3)] * 3],
        quats=[[1.0, 0, 0, 0]], opacity_logits=[4.0], sh_dc=[colour_dc],
        sh_rest=sh_rest)


def test_model_render_save_load(tmp_path):
    # A red Gaussian 4 units in front of the camera, at the image centre.
    model = one_gaussian([2.0, -2.0, -2.0])
    assert len(model) == 1 and model.sh_degree == 0 and model.path is None
    camera = watergs.Camera(64, 48, 60, 60, t=[0, 0, 4])
    image = model.render(camera)
    assert image.shape == (48, 64, 3) and image.dtype == np.float32
    centre = image[24, 32]
    assert centre[0] > 0.8 and centre[1] < 0.05 and centre[2] < 0.05
    assert np.all(image[0, 0] == 0)
    white = model.render(camera, background="white")
    assert np.allclose(white[0, 0], 1)
    assert np.allclose(model.render(camera, background=(0, 0, 1))[0, 0],
                       [0, 0, 1])
    # Behind the camera: nothing.
    assert np.all(model.render(watergs.Camera(64, 48, 60, 60,
                                              t=[0, 0, -4])) == 0)

    rest = np.random.default_rng(0).normal(0, 0.1, (1, 15, 3))
    model = one_gaussian([0.5, 0.1, -0.3], sh_rest=rest)
    path = tmp_path / "one.ply"
    model.save(path)
    loaded = watergs.Model.load(path)
    assert loaded.path == str(path) and loaded.sh_degree == 3
    for name in ("means", "log_scales", "quats", "opacity_logits", "sh_dc",
                 "sh_rest"):
        assert np.array_equal(getattr(loaded, name), getattr(model, name))
    assert np.allclose(loaded.sh_rest, rest.astype(np.float32))
    assert np.array_equal(loaded.render(camera), model.render(camera))
    # SH degree 0 drops the view-dependent part.
    assert not np.array_equal(model.render(camera, sh_degree=0),
                              model.render(camera))
