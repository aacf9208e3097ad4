"""Bad input through the Python module: missing and malformed files, wrong
types, NaN arrays. Each raises one exception with a one-line message (the
CLI's own, word for word, where the CLI can be given the same input) and
leaves the interpreter running and no output behind."""

import math
import os
import subprocess
import sys

import numpy as np
import pytest

import watergs
from conftest import DECODER, DOWNSCALE, MESSAGE, SCENE, watergs_bin


def cli_error(*args):
    """The one-line message `watergs ARGS` prints on stderr (exit code 1)."""
    run = subprocess.run([watergs_bin(), *map(str, args)], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 1, run.stdout + run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), run.stderr
    return lines[0][len("error: "):]


def tiny_model():
    """Two Gaussians at the origin."""
    return watergs.Model.from_arrays(np.zeros((2, 3)), np.zeros((2, 3)),
                                     [[1, 0, 0, 0]] * 2, np.zeros(2),
                                     np.zeros((2, 3)))


def raised(call, *args, **kwargs):
    with pytest.raises(watergs.Error) as info:
        call(*args, **kwargs)
    message = str(info.value)
    assert message and "\n" not in message
    return message


def test_error_is_a_runtime_error():
    assert issubclass(watergs.Error, RuntimeError)


def test_missing_files_raise_the_clis_message(tmp_path):
    missing = tmp_path / "no_such_scene"
    out = tmp_path / "out"
    message = raised(watergs.train, missing, out, quiet=True)
    assert str(missing) in message
    assert message == cli_error("train", f"--workspace_path={missing}",
                                f"--output_path={out}")
    assert not out.exists()

    ply = tmp_path / "missing.ply"
    message = raised(watergs.extract, ply, SCENE, DECODER, message=MESSAGE,
                     quiet=True)
    assert str(ply) in message
    assert message == cli_error("extract", f"--input_path={ply}",
                                f"--workspace_path={SCENE}",
                                f"--decoder={DECODER}",
                                f"--message={MESSAGE}",
                                f"--json={tmp_path / 'x.json'}")
    assert str(ply) in raised(watergs.Model.load, ply)
    assert str(missing) in raised(watergs.Workspace, missing)


def test_malformed_files_raise(tmp_path):
    garbage = tmp_path / "garbage.ply"
    garbage.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement ")
    assert str(garbage) in raised(watergs.Model.load, garbage)
    message = raised(watergs.render, garbage, SCENE, quiet=True)
    assert message == cli_error("render", f"--input_path={garbage}",
                                f"--workspace_path={SCENE}",
                                f"--output_path={tmp_path / 'renders'}")
    # A PLY is not a decoder.
    ply = tmp_path / "model.ply"
    tiny_model().save(ply)
    assert str(ply) in raised(watergs.extract, ply, SCENE, ply,
                              message=MESSAGE, quiet=True)


def test_bad_options_raise_the_clis_message(tmp_path):
    out = tmp_path / "out"
    for options, words in [
        ({"iterations": "abc"}, ["--iterations=abc"]),
        ({"bogus_option": 1}, ["--bogus_option=1"]),
        ({"downscale": 3}, ["--downscale=3"]),
        ({"background": (2, 0, 0)}, ["--background=2,0,0"]),
    ]:
        message = raised(watergs.train, SCENE, out, quiet=True, **options)
        assert message == cli_error("train", f"--workspace_path={SCENE}",
                                    f"--output_path={out}", *words)
        assert not out.exists()
    ply = tmp_path / "in.ply"
    tiny_model().save(ply)
    wm = tmp_path / "wm.ply"
    message = raised(watergs.embed, ply, SCENE, DECODER, "hex:zz", wm,
                     quiet=True)
    assert "zz" in message
    assert message == cli_error("embed", f"--input_path={ply}",
                                f"--workspace_path={SCENE}",
                                f"--decoder={DECODER}", "--message=hex:zz",
                                f"--output_path={wm}")
    assert not wm.exists()


def test_wrong_types_raise_type_error(tmp_path):
    for call in [
        lambda: watergs.train(5, tmp_path / "out"),
        lambda: watergs.train(SCENE, tmp_path / "out", iterations={"a": 1}),
        lambda: watergs.train(SCENE, tmp_path / "out", progress=5),
        lambda: watergs.extract(SCENE, SCENE, None),
        lambda: watergs.Model.load(3.5),
        lambda: watergs.Workspace(SCENE, downscale="2"),
        lambda: watergs.Camera("64", 48, 50, 50),
        lambda: watergs.Camera(64, 48, "fifty", 50),
        lambda: watergs.Camera(64, 48, 50, 50, R="identity"),
        lambda: watergs.run(42),
    ]:
        with pytest.raises(TypeError) as info:
            call()
        assert "\n" not in str(info.value)
    assert not (tmp_path / "out").exists()


def test_nan_and_badly_shaped_arrays_raise(tmp_path):
    eye = np.eye(3)
    nan_r = eye.copy()
    nan_r[1, 2] = math.nan
    assert "NaN" in raised(watergs.Camera, 64, 48, 50, 50, R=nan_r)
    assert "NaN" in raised(watergs.Camera, 64, 48, 50, 50, t=[0, math.inf, 0])
    assert "NaN" in raised(watergs.Camera, 64, 48, math.nan, 50)
    assert "shape (3, 3)" in raised(watergs.Camera, 64, 48, 50, 50,
                                    R=np.eye(2))
    assert "rotation" in raised(watergs.Camera, 64, 48, 50, 50, R=2 * eye)
    assert "width" in raised(watergs.Camera, 0, 48, 50, 50)
    assert "fx" in raised(watergs.Camera, 64, 48, -1, 50)

    n = 4
    arrays = dict(means=np.zeros((n, 3)), log_scales=np.full((n, 3), -2.0),
                  quats=np.tile([1.0, 0, 0, 0], (n, 1)),
                  opacity_logits=np.zeros(n), sh_dc=np.zeros((n, 3)))
    for name in arrays:
        bad = dict(arrays)
        bad[name] = arrays[name].copy()
        bad[name].flat[1] = math.nan
        assert name in raised(watergs.Model.from_arrays, **bad)
    bad = dict(arrays, log_scales=np.zeros((n, 2)))
    assert "log_scales" in raised(watergs.Model.from_arrays, **bad)
    bad = dict(arrays, sh_rest=np.zeros((n, 5, 3)))
    assert "sh_rest" in raised(watergs.Model.from_arrays, **bad)
    bad = dict(arrays, quats=np.zeros((n, 4)))
    assert "quaternion" in raised(watergs.Model.from_arrays, **bad)

    model = watergs.Model.from_arrays(**arrays)
    camera = watergs.Camera(64, 48, 50, 50, t=[0, 0, 3])
    assert "background" in raised(model.render, camera,
                                  background=[0.5, math.nan, 0])
    assert "sh_degree" in raised(model.render, camera, sh_degree=2)
    # NaN options never reach the command.
    assert "finite" in raised(watergs.train, SCENE, tmp_path / "out",
                              position_lr_max_steps=math.nan)
    assert "finite" in raised(watergs.embed, "in.ply", SCENE, DECODER,
                              MESSAGE, tmp_path / "wm.ply",
                              gamma=float("nan"))
    assert not (tmp_path / "wm.ply").exists()


def test_bad_view_index_raises_index_error():
    workspace = watergs.Workspace(SCENE, downscale=DOWNSCALE)
    with pytest.raises(IndexError):
        workspace.camera(len(workspace))
    assert workspace.camera(-1).width == workspace.camera(0).width


def test_import_and_errors_without_numpy():
    # The module imports, and says what is missing, where numpy is absent
    # (another interpreter on PATH, a bare virtual environment).
    code = (
        "import sys\n"
        "sys.modules['numpy'] = None\n"
        "import watergs\n"
        "print(watergs.__version__)\n"
        "print(watergs.Camera(64, 48, 50, 50).width)\n"
        "try:\n"
        f"    watergs.render('x.ply', {str(SCENE)!r})\n"
        "except ImportError as e:\n"
        "    print('ImportError', e)\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True,
                         text=True, timeout=120, env=os.environ)
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()
    assert lines[0] == watergs.__version__
    assert lines[1] == "64"
    assert lines[2].startswith("ImportError") and "numpy" in lines[2]


def test_pipeline_names_a_missing_photo_folder_as_the_cli_does(tmp_path):
    missing = tmp_path / "no_photos"
    message = raised(watergs.pipeline, missing, DECODER, "text:X",
                     tmp_path / "out", quiet=True)
    assert str(missing) in message
    assert message == cli_error("pipeline", "--image_path", missing,
                                "--decoder", DECODER, "--message", "text:X",
                                "--output_path", tmp_path / "out")
    assert not (tmp_path / "out").exists()
