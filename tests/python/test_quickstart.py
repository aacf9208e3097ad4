"""The README's Python example (examples/quickstart.py) runs as written:
it trains, embeds and extracts, and the verdicts it prints are right."""

import os
import re
import subprocess
import sys

from conftest import ROOT


def test_quickstart_example(tmp_path):
    run = subprocess.run(
        [sys.executable, str(ROOT / "examples" / "quickstart.py"),
         str(tmp_path / "out")],
        capture_output=True, text=True, timeout=600, env=os.environ,
        cwd=tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    lines = run.stdout.splitlines()
    assert len(lines) == 3, run.stdout
    assert re.fullmatch(r"trained: \d+ Gaussians, PSNR \d+\.\d dB", lines[0])
    assert re.fullmatch(r"unmarked: BER .*, watermark absent", lines[1])
    watermarked = re.fullmatch(
        r"watermarked: BER (\d+\.\d)%, p-value (\S+), watermark present",
        lines[2])
    assert watermarked, lines[2]
    assert float(watermarked.group(1)) < 10
    assert float(watermarked.group(2)) < 1e-9
    assert (tmp_path / "out" / "wm.ply").is_file()
