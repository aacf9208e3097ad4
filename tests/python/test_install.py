"""`import watergs` without PYTHONPATH, from any folder, after the build:
the watergs.pth the build writes into the interpreter's site folder names
this build's module folder, and a fresh interpreter (-I: no PYTHONPATH, no
current folder on the path) imports this build's module through it."""

import os
import subprocess
import sys

import pytest


def test_build_makes_watergs_importable_from_any_folder(tmp_path):
    pth = os.environ.get("WATERGS_PYTHON_PTH_FILE")
    module_dir = os.environ.get("WATERGS_PYTHON_DIR")
    if not pth or not module_dir:
        pytest.skip("configured with -DWATERGS_PYTHON_PTH=OFF: import "
                    "watergs with PYTHONPATH=<build>/python")
    if not os.access(os.path.dirname(pth), os.W_OK):
        pytest.skip(f"{os.path.dirname(pth)} is not writable here: import "
                    "watergs with PYTHONPATH=<build>/python")
    with open(pth, encoding="utf-8") as f:
        named = f.read().strip()
    if named != module_dir and os.path.isdir(named):
        pytest.skip(f"another build tree ({named}) was built after this one "
                    "and wrote the import path")
    assert named == module_dir
    run = subprocess.run(
        [sys.executable, "-I", "-c",
         "import watergs; print(watergs.__file__); print(watergs.__version__)"],
        capture_output=True, text=True, cwd=tmp_path, timeout=60)
    assert run.returncode == 0, run.stderr
    path, version = run.stdout.split()
    assert path == os.path.join(module_dir, "watergs", "__init__.py")
    assert version
