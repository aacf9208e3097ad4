"""Shared fixtures of the Python module's tests (tests/python): the demo
scene at 1/8 resolution (60x45 pixels, 48 views), the shipped decoder, and a
model trained on it for a few seconds. CTest runs each test file with
PYTHONPATH=<build>/python and WATERGS_BIN, WATERGS_SOURCE_DIR set."""

import os
import pathlib
import shutil

import pytest

ROOT = pathlib.Path(
    os.environ.get("WATERGS_SOURCE_DIR",
                   pathlib.Path(__file__).resolve().parents[2]))
SCENE = ROOT / "datasets_scripts" / "demo_scene"
DECODER = ROOT / "watermark" / "models" / "decoder_48.bin"
# 6 ASCII characters: the shipped decoder's 48 bits.
MESSAGE = "text:WGS-26"
DOWNSCALE = 8


def watergs_bin():
    """The CLI the module's answers are compared with."""
    path = os.environ.get("WATERGS_BIN") or shutil.which("watergs") or str(
        ROOT / "build" / "plugin" / "watergs")
    if not os.path.exists(path):
        pytest.skip(f"no watergs CLI at {path} (set WATERGS_BIN)")
    return path


@pytest.fixture(scope="session")
def trained(tmp_path_factory):
    """A TrainResult: 100 iterations on the demo scene at 1/8 resolution,
    every 8th view held out."""
    import watergs
    out = tmp_path_factory.mktemp("trained") / "train"
    return watergs.train(SCENE, out, downscale=DOWNSCALE, iterations=100,
                         test_iterations=100, split="train", quiet=True)


# Under CTest (which sets WATERGS_PYTEST_SKIP_CODE, the test's
# SKIP_RETURN_CODE) a file in which a test was skipped and none failed exits
# with that code, so that CTest lists it as skipped, not passed; pytest's -rs
# summary above says which test and why. Run by hand, pytest's own exit codes.
def pytest_sessionfinish(session, exitstatus):
    code = os.environ.get("WATERGS_PYTEST_SKIP_CODE")
    if not code or exitstatus != 0:
        return
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None and reporter.stats.get("skipped"):
        session.exitstatus = int(code)
