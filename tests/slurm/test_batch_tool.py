#!/usr/bin/env python3
"""Tests of scripts/slurm/batch_tool.py, the bookkeeping of watergs_batch.sh, without Slurm: manifest
parsing and its one-line errors, which scenes a resubmission runs, and the aggregate table. Runs the tool
as the driver does (a subprocess); Python standard library only."""
import csv
import json
import os
import subprocess
import sys
import tempfile
import unittest

TOOL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "scripts", "slurm", "batch_tool.py")


def write(path, text):
    with open(path, "w") as f:
        f.write(text)


def read(path):
    with open(path) as f:
        return f.read()


def run(*args):
    p = subprocess.run([sys.executable, TOOL, *args], capture_output=True, text=True)
    return p.returncode, p.stdout, p.stderr


class BatchToolTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.dir = self.tmp.name
        for name in ("ws_a", "ws_b"):
            os.makedirs(os.path.join(self.dir, "data", name, "images"))
            os.makedirs(os.path.join(self.dir, "data", name, "sparse", "0"))
        self.decoder = os.path.join(self.dir, "decoder.bin")
        write(self.decoder, "x")
        self.table = os.path.join(self.dir, "scenes.tsv")
        self.out = os.path.join(self.dir, "out")

    def tearDown(self):
        self.tmp.cleanup()

    def manifest(self, text, *sets):
        path = os.path.join(self.dir, "data", "manifest.txt")
        write(path, text)
        defaults = ["--set", f"decoder={self.decoder}", "--set", "message=text:WGS-26", *sets]
        return run("manifest", "--manifest", path, "--output", self.table, *defaults)

    def scenes(self):
        text = read(self.table).splitlines()
        lines = [l for l in text if not l.startswith("#")]
        header = text[0][2:].split("\t")
        return [dict(zip(header, l.split("\t"))) for l in lines]

    def test_manifest_defaults_overrides_quoting_and_relative_paths(self):
        rc, out, err = self.manifest(
            "# two scenes\n\nws_a   # trailing comment\n"
            "ws_b name=b2 seed=3 downscale=4 message=\"text:OWN 02\" embed_args=\"--gamma 0.03 --crop_size 0\"\n",
            "--set", "downscale=8")
        self.assertEqual(rc, 0, err)
        self.assertEqual(out.strip(), "2")
        a, b = self.scenes()
        self.assertEqual((a["name"], a["workspace"]), ("ws_a", os.path.join(self.dir, "data", "ws_a")))
        self.assertEqual((a["downscale"], a["message"], a["seed"]), ("8", "text:WGS-26", ""))
        self.assertEqual(a["attacks"], "identity,gn:0.01,dropout:0.1,crop:0.1")
        self.assertEqual((b["name"], b["downscale"], b["seed"], b["message"]), ("b2", "4", "3", "text:OWN 02"))
        # row: the fields, the fingerprint, then each option list as its length and words.
        rc, out, err = run("row", "--scenes", self.table, "--index", "1")
        self.assertEqual(rc, 0, err)
        items = out.split("\0")[:-1]
        self.assertEqual(items[0], "b2")
        self.assertEqual(items[14:], ["0", "4", "--gamma", "0.03", "--crop_size", "0", "0"])
        self.assertNotEqual(run("row", "--scenes", self.table, "--index", "2")[0], 0)

    def test_manifest_errors_name_the_line_and_write_nothing(self):
        cases = {
            "ws_a colour=red\n": "manifest.txt:1: unknown key 'colour'",
            "ws_a\nws_a\n": "manifest.txt:2: scene name 'ws_a' is also on line 1",
            "ws_a downscale=0\n": "manifest.txt:1: downscale '0' is not a whole number >= 1",
            "ws_a train_iterations=1e3\n": "manifest.txt:1: train_iterations '1e3' is not a whole number",
            "missing\n": "manifest.txt:1: workspace '" + os.path.join(self.dir, "data", "missing") + "' is not a folder",
            "ws_a ply=nowhere.ply\n": "manifest.txt:1: ply '",
            "ws_a message=''\n": "manifest.txt:1: no message for scene 'ws_a'",
            "ws_a message=\"open\n": "manifest.txt:1: No closing quotation",
            "ws_a name=a/b\n": "manifest.txt:1: scene name 'a/b' must be",
            "ws_a extra\n": "manifest.txt:1: 'extra' is not key=value",
            "# nothing\n": "no scene in the manifest",
        }
        os.makedirs(os.path.join(self.dir, "data", "bad", "images"))
        cases["bad\n"] = "has no sparse/0/ folder"
        for text, expected in cases.items():
            with self.subTest(text=text):
                rc, _, err = self.manifest(text)
                self.assertNotEqual(rc, 0)
                self.assertIn(expected, err)
                self.assertEqual(len(err.strip().splitlines()), 1, err)
                self.assertFalse(os.path.exists(self.table))

    def status(self, name, state, **kw):
        os.makedirs(os.path.join(self.out, "scenes", name), exist_ok=True)
        args = ["status", "--file", os.path.join(self.out, "scenes", name, "status.json"), "--scene", name,
                "--state", state]
        for k, v in kw.items():
            args += [f"--{k}", v]
        rc, _, err = run(*args)
        self.assertEqual(rc, 0, err)

    def fingerprint(self, index):
        return run("row", "--scenes", self.table, "--index", str(index))[1].split("\0")[13]

    def test_pending_skips_done_and_failed_resumes_the_rest(self):
        names = ["s0", "s1", "s2", "s3", "s4", "s5"]
        self.assertEqual(self.manifest("".join(f"ws_a name={n}\n" for n in names))[0], 0)
        self.status("s0", "done", fingerprint=self.fingerprint(0))
        self.status("s1", "failed", step="train", error="error: x: truncated")
        self.status("s2", "interrupted", error="terminated by SIGTERM")
        self.status("s3", "running")
        os.makedirs(os.path.join(self.out, "scenes", "s4"))
        write(os.path.join(self.out, "scenes", "s4", "status.json"), "{\"state\": ")  # damaged
        rc, out, err = run("pending", "--scenes", self.table, "--output_path", self.out)
        self.assertEqual(rc, 0, err)
        self.assertEqual(out.strip(), "2,3,4,5")
        self.assertIn("skip s1: failed at train: error: x: truncated (--retry_failed runs it again)", err)
        rc, out, err = run("pending", "--scenes", self.table, "--output_path", self.out, "--retry_failed")
        self.assertEqual(out.strip(), "1,2,3,4,5")
        # Done with other options than the manifest has now: kept, with a warning saying how to redo it.
        self.assertEqual(self.manifest("".join(f"ws_a name={n} seed=7\n" for n in names))[0], 0)
        rc, out, err = run("pending", "--scenes", self.table, "--output_path", self.out)
        self.assertEqual(out.strip(), "2,3,4,5")
        self.assertIn("skip s0: done, but with other manifest options than now", err)

    def write_eval(self, name, bers, raw_ber, psnr):
        robustness = [{"model": "watermarked", "attack": a, "kind": "3d", "ber": b} for a, b in bers.items()]
        robustness.append({"model": "watermarked", "attack": "jpeg:50", "kind": "2d", "ber": 0.5})
        robustness.append({"model": "raw", "attack": "identity", "kind": "3d", "ber": raw_ber})
        report = {"num_bits": 48, "watermarked_gaussians": 1234, "robustness": robustness,
                  "quality": [{"comparison": "watermarked vs ground truth", "mean": {"psnr": psnr}},
                              {"comparison": "watermarked vs raw renders", "mean": {"psnr": 30.0}},
                              {"comparison": "raw vs ground truth", "mean": {"psnr": psnr + 1}}]}
        d = os.path.join(self.out, "scenes", name)
        write(os.path.join(d, "eval.json"), json.dumps(report))
        for step, seconds in (("train", "10.5"), ("embed", "20.25"), ("eval", "3")):
            write(os.path.join(d, f"{step}.seconds"), seconds + "\n")

    def test_aggregate_rows_failures_and_missing(self):
        text = ("ws_a name=good attacks=identity,gn:0.01\nws_a name=broken\nws_b name=never\n"
                "ws_b name=odd attacks=identity,crop:0.1\n")
        self.assertEqual(self.manifest(text)[0], 0)
        self.status("good", "done")
        self.write_eval("good", {"identity": 1 / 48, "gn:0.01": 3 / 48}, 0.5, 25.0)
        self.status("broken", "failed", step="train", error="error: ws/sparse/0/images.bin: truncated")
        self.status("odd", "done")  # done, but its eval report is missing: reported, not a crash
        rc, out, err = run("aggregate", "--scenes", self.table, "--output_path", self.out)
        self.assertEqual(rc, 0, err)
        rows = {r["scene"]: r for r in csv.DictReader(read(os.path.join(self.out, "summary.csv")).splitlines())}
        self.assertEqual(list(rows), ["good", "broken", "never", "odd"])
        good = rows["good"]
        self.assertEqual((good["state"], good["bits"], good["gaussians"]), ("done", "48", "1234"))
        self.assertAlmostEqual(float(good["ber_identity"]), 100 / 48, places=3)
        self.assertAlmostEqual(float(good["ber_gn:0.01"]), 300 / 48, places=3)
        self.assertEqual(good["ber_crop:0.1"], "")  # other scenes' attacks: columns present, empty here
        self.assertEqual(good["ber_dropout:0.1"], "")
        self.assertEqual((good["ber_raw"], good["psnr_wm"], good["psnr_raw"]), ("50.0000", "25.000", "26.000"))
        self.assertEqual((good["train_s"], good["embed_s"], good["eval_s"], good["total_s"]),
                         ("10.5", "20.2", "3.0", "33.8"))
        self.assertEqual((rows["broken"]["state"], rows["broken"]["step"]), ("failed", "train"))
        self.assertEqual(rows["never"]["state"], "not run")
        self.assertEqual((rows["odd"]["state"], rows["odd"]["step"]), ("failed", "aggregate"))
        self.assertIn("eval.json", rows["odd"]["error"])
        summary = json.loads(read(os.path.join(self.out, "summary.json")))
        self.assertEqual((summary["scenes"], summary["done"], summary["problems"]), (4, 1, 3))
        self.assertEqual([f["scene"] for f in summary["failed"]], ["broken", "never", "odd"])
        md = read(os.path.join(self.out, "summary.md"))
        self.assertEqual(md, out)
        self.assertIn("| good | 2.08 | 6.25 |  |  | 50.00 | 25.00 | 26.00 | 10.5 | 20.2 | 3.0 |", md)
        self.assertIn("- broken: failed at train: error: ws/sparse/0/images.bin: truncated", md)


if __name__ == "__main__":
    unittest.main()
