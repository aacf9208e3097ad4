"""The pipeline commands through Python (train, embed, extract, attack,
render) on the demo scene at 1/8 resolution: results as Python objects and
numpy arrays that agree with what the CLI writes for the same input,
progress callbacks, and Ctrl-C / a raising callback stopping a run cleanly."""

import json
import os
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

import watergs
from conftest import DECODER, DOWNSCALE, MESSAGE, SCENE, watergs_bin


def test_train_result(trained):
    assert trained.iterations == 100
    assert os.path.isfile(trained.ply_path)
    assert trained.report["metrics_split"] == "test"
    assert trained.report["num_metric_views"] == 6
    # Far above a black image's PSNR on this scene after 100 iterations.
    assert 12 < trained.psnr < 60
    model = trained.load_model()
    assert len(model) == trained.num_gaussians > 0
    assert model.means.shape == (len(model), 3)
    assert model.means.dtype == np.float32
    assert model.sh_rest.shape == (len(model), 15, 3)


def test_train_progress_callback(tmp_path):
    events = []
    watergs.train(SCENE, tmp_path / "run", downscale=DOWNSCALE,
                  iterations=20, progress=events.append, quiet=True)
    assert [e.done for e in events[:-1]] == list(range(1, 21))
    assert all(e.label == "train" and e.total == 20 for e in events)
    assert "Gaussians" in events[0].status
    assert events[-1].finished and events[-1].done == 20
    assert not any(e.finished for e in events[:-1])


def test_raising_callback_stops_training_cleanly(tmp_path):
    out = tmp_path / "run"

    def stop(progress):
        if progress.done == 5:
            raise ValueError("stop here")

    with pytest.raises(ValueError, match="stop here"):
        watergs.train(SCENE, out, downscale=DOWNSCALE, iterations=2000,
                      progress=stop, quiet=True)
    # The run's folder goes, as after any error before it is written.
    assert not out.exists()
    # The module still works after the unwinding.
    assert watergs.train(SCENE, out, downscale=DOWNSCALE, iterations=3,
                         quiet=True).iterations == 3


def test_option_values_and_thread_count_restored(trained, tmp_path):
    # numpy values and lists as the command line writes them.
    one = watergs.train(SCENE, tmp_path / "one", downscale=DOWNSCALE,
                        iterations=np.int64(2), num_threads=1,
                        split="train", background=np.ones(3),
                        test_iterations=[1, 2],
                        compact_optimizer=np.bool_(False),
                        sh_degree=None, quiet=True)
    assert one.report["eval"] is True and one.report["iterations"] == 2
    assert one.report["compact_optimizer"] is False
    assert one.report["sh_degree"] == 3
    log = (tmp_path / "one" / "train_log.jsonl").read_text().splitlines()
    assert sum("test_psnr" in line for line in log) == 2, log
    assert one.report["num_threads"] == 1
    after = watergs.train(SCENE, tmp_path / "after", downscale=DOWNSCALE,
                          iterations=2, quiet=True)
    assert after.report["num_threads"] == trained.report["num_threads"]


def test_ctrl_c_stops_training(tmp_path):
    out = tmp_path / "run"
    stop = threading.Event()

    def ctrl_c_once_training_started():
        # A real SIGINT as soon as training has created its folder (not after
        # a fixed time, which a fast machine could outrun). No progress
        # callback runs, so only the C++ loop's own check can notice it.
        while not stop.is_set():
            if out.exists():
                os.kill(os.getpid(), signal.SIGINT)
                return
            time.sleep(0.005)

    watcher = threading.Thread(target=ctrl_c_once_training_started)
    watcher.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            watergs.train(SCENE, out, downscale=DOWNSCALE, iterations=2000,
                          quiet=True)
    finally:
        stop.set()
        watcher.join()
    # No bound on the wall time (a loaded machine can take any time): a
    # SIGINT that only ran once training returned would leave the finished
    # run's folder, which a stopped run removes.
    assert not out.exists()


def test_embed_extract_agree_with_the_cli(trained, tmp_path):
    events = []
    wm = watergs.embed(trained.ply_path, SCENE, DECODER, MESSAGE,
                       tmp_path / "wm.ply", downscale=DOWNSCALE, iterations=30,
                       crop_size=0, densify="off", check_every=15,
                       check_views=2, patience=0, progress=events.append,
                       quiet=True)
    assert os.path.isfile(wm.output_path)
    assert {e.label for e in events} == {"embed"}
    assert events[-1].finished and events[-1].total == 30
    assert len(wm.load_model()) == trained.num_gaussians

    result = watergs.extract(wm.output_path, SCENE, DECODER, message=MESSAGE,
                             downscale=DOWNSCALE, max_views=8, quiet=True)
    assert result.num_bits == 48 and result.num_views == 8
    assert result.recovered_bits.dtype == np.uint8
    assert result.recovered_bits.shape == (48,)
    assert set(np.unique(result.recovered_bits)) <= {0, 1}
    assert result.expected_bits.shape == (48,)
    assert result.bit_errors == int(
        np.sum(result.recovered_bits != result.expected_bits))
    assert result.ber == pytest.approx(result.bit_errors / 48)
    assert 0 <= result.p_value <= 1
    assert result.verdict in ("watermark present", "watermark absent",
                              "inconclusive")
    assert result.present == (result.verdict == "watermark present")
    assert result.view_ber.shape == (8,) and result.view_ber.dtype == np.float64
    assert len(result.view_names) == 8
    assert result.mean_logits.shape == (48,)
    assert np.array_equal(result.recovered_bits,
                          (result.mean_logits > 0).astype(np.uint8))

    # The CLI's JSON for the same input is the same result.
    cli_json = tmp_path / "cli.json"
    subprocess.run([watergs_bin(), "extract", f"--input_path={wm.output_path}",
                    f"--workspace_path={SCENE}", f"--decoder={DECODER}",
                    f"--message={MESSAGE}", f"--downscale={DOWNSCALE}",
                    "--max_views=8", f"--json={cli_json}"], check=True,
                   capture_output=True, timeout=300)
    # Each names the command that wrote it (the module runs the CLI's
    # command in-process, so both are `watergs extract ...`), at one commit.
    cli_report = json.loads(cli_json.read_text())
    cli_provenance = cli_report.pop("provenance")
    report = dict(result.report)
    provenance = report.pop("provenance")
    assert cli_report == report
    assert cli_provenance["command"].startswith("watergs extract --input_path=")
    assert provenance["command"].startswith("watergs extract ")
    assert cli_provenance["commit"] == provenance["commit"] == watergs.__commit__

    # Without a claimed message: the bits, no verdict.
    bare = watergs.extract(wm.output_path, SCENE, DECODER, downscale=DOWNSCALE,
                           max_views=8, quiet=True)
    assert bare.verdict is None and bare.view_ber is None
    assert np.array_equal(bare.recovered_bits, result.recovered_bits)


def test_render_matches_model_render(trained, tmp_path):
    result = watergs.render(trained.ply_path, SCENE, downscale=DOWNSCALE,
                            quiet=True)
    workspace = watergs.Workspace(SCENE, downscale=DOWNSCALE)
    test_views = workspace.test_views()
    assert result.output_path is None
    assert result.names == [workspace.names[v] for v in test_views]
    assert len(result.images) == len(result.psnr) == 6
    camera = workspace.camera(test_views[0])
    assert result.images[0].shape == (camera.height, camera.width, 3)
    assert result.images[0].dtype == np.uint8
    assert result.mean_psnr == pytest.approx(np.mean(result.psnr))
    # The PNG is the float render, rounded to 8 bits.
    direct = trained.load_model().render(camera)
    assert direct.dtype == np.float32 and direct.shape == (45, 60, 3)
    assert np.abs(result.images[0] / 255.0 - direct).max() <= 0.5 / 255 + 1e-6

    kept = watergs.render(trained.ply_path, SCENE, tmp_path / "renders",
                          downscale=DOWNSCALE, split="train", quiet=True)
    assert len(kept.images) == 42
    assert (tmp_path / "renders" / "render_report.json").is_file()


def test_attack_and_quiet(trained, tmp_path, capfd):
    out = tmp_path / "attacked.ply"
    capfd.readouterr()
    noisy = watergs.attack(trained.ply_path, "gn:0.01,dropout:0.5", out,
                           quiet=True)
    assert capfd.readouterr() == ("", "")
    assert noisy.transform is None
    model = noisy.load_model()
    raw = trained.load_model()
    assert 0.3 * len(raw) < len(model) < 0.7 * len(raw)
    moved = watergs.attack(trained.ply_path, ["similarity:30,1,0,0,1.5"], out,
                           quiet=True)
    assert moved.transform.startswith("similarity:")
    assert os.path.isfile(moved.transform_path)
    # A later attack that does not move the scene has no transform, though
    # the earlier file is still there.
    capfd.readouterr()
    again = watergs.attack(trained.ply_path, "sh0", out)
    assert again.transform is None and os.path.exists(moved.transform_path)
    assert f"wrote {out}" in capfd.readouterr().out


def test_run_any_command_and_help(trained, capfd):
    watergs.run("ply_info", input_path=trained.ply_path)
    assert "Gaussians" in capfd.readouterr().out
    text = watergs.help("embed")
    assert "--free_view_fraction" in text and "--gamma" in text
    assert "--free_view_fraction" in watergs.embed.__doc__


def test_booleans_are_written_both_ways():
    # False turns off an option that defaults on (detect's refine_pose), as
    # every boolean takes --name=0|1; None leaves the default.
    from watergs import _commands
    assert _commands._words("detect", {"refine_pose": False, "x": None,
                                       "resume": True, "n": 3}) == [
        "--refine_pose=0", "--resume=1", "--n=3"]
