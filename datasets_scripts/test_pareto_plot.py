#!/usr/bin/env python3
"""Checks of pareto_plot.py's Pareto fronts and CSV collection on tiny hand-made inputs
(runs in well under a second: python3 datasets_scripts/test_pareto_plot.py)."""

import json
import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, HERE)
import pareto_plot  # noqa: E402


def brute_front(points, maximize_y):
    """Non-dominated indices by the definition, for comparison."""
    sign = -1 if maximize_y else 1
    front = []
    for i, (xi, yi) in enumerate(points):
        if xi is None or yi is None:
            continue
        dominated = False
        for j, (xj, yj) in enumerate(points):
            if j == i or xj is None or yj is None:
                continue
            if xj <= xi and sign * yj <= sign * yi and (xj < xi or sign * yj < sign * yi):
                dominated = True
        if not dominated:
            front.append(i)
    return front


class ParetoFrontTest(unittest.TestCase):
    def test_hand_example_maximize(self):
        # (time, psnr): 1 beats 0 in both; 2 is slower but better; 3 is slower and worse than 2.
        points = [(2.0, 20.0), (1.0, 21.0), (3.0, 25.0), (4.0, 24.0), (5.0, 26.0)]
        self.assertEqual(pareto_plot.pareto_front(points, maximize_y=True), [1, 2, 4])

    def test_hand_example_minimize(self):
        # (time, ber): lower is better in both.
        points = [(1.0, 0.5), (2.0, 0.4), (3.0, 0.45), (4.0, 0.1)]
        self.assertEqual(pareto_plot.pareto_front(points, maximize_y=False), [0, 1, 3])

    def test_missing_values_are_never_on_the_front(self):
        points = [(1.0, None), (None, 30.0), (2.0, 20.0), (float("nan"), 40.0)]
        self.assertEqual(pareto_plot.pareto_front(points, maximize_y=True), [2])

    def test_equal_points_are_all_kept(self):
        points = [(1.0, 10.0), (1.0, 10.0), (1.0, 9.0)]
        self.assertEqual(pareto_plot.pareto_front(points, maximize_y=True), [0, 1])

    def test_matches_definition_on_a_grid(self):
        # Deterministic pseudo-random points with ties on both axes.
        points = [((7 * i) % 11 * 1.0, (13 * i) % 7 * 1.0) for i in range(40)]
        for maximize in (True, False):
            self.assertEqual(pareto_plot.pareto_front(points, maximize),
                             sorted(set(brute_front(points, maximize))))

    def test_three_objectives(self):
        rows = [{"t": 1, "b": 0.4, "p": 30}, {"t": 2, "b": 0.3, "p": 31},
                {"t": 3, "b": 0.35, "p": 29}, {"t": 3, "b": 0.2, "p": 25}]
        front = pareto_plot.pareto_front_nd(rows, [("t", False), ("b", False), ("p", True)])
        self.assertEqual(front, [0, 1, 3])


class TrainCsvTest(unittest.TestCase):
    def test_front_is_per_downscale(self):
        with tempfile.TemporaryDirectory() as tmp:
            runs = []
            # The 1/4-res run is faster and scores higher PSNR (easier, smaller images), but must
            # not push the 1/2-res run off its own front.
            for name, ds, lines in [("a", 4, [(100, 1.0, 25.0), (200, 2.0, 26.0)]),
                                    ("b", 2, [(100, 3.0, 20.0), (200, 6.0, 19.0)])]:
                d = os.path.join(tmp, name)
                os.makedirs(d)
                with open(os.path.join(d, "sweep_meta.json"), "w") as f:
                    json.dump({"setting": name, "downscale": ds, "iterations": 200,
                               "densify_until_iter": 15000, "wall_seconds": 9.0}, f)
                with open(os.path.join(d, "train_log.jsonl"), "w") as f:
                    f.write(json.dumps({"iteration": 50, "seconds": 0.5, "num_gaussians": 5}) + "\n")
                    for it, sec, psnr in lines:
                        f.write(json.dumps({"iteration": it, "seconds": sec, "num_gaussians": 5,
                                            "test_psnr": psnr, "test_ssim": 0.5}) + "\n")
                runs.append(d)
            out = os.path.join(tmp, "t.csv")
            subprocess.run([sys.executable, os.path.join(HERE, "pareto_plot.py"), "train-csv",
                            *runs, "--out", out], check=True, capture_output=True)
            rows = pareto_plot.read_csv(out)
            self.assertEqual([(r["setting"], r["iteration"], r["pareto"]) for r in rows],
                             [("a", "100", "1"), ("a", "200", "1"),
                              ("b", "100", "1"), ("b", "200", "0")])
            # Only the last row of a run is a run end; each resolution has one here.
            self.assertEqual([(r["final"], r["pareto_final"]) for r in rows],
                             [("0", "0"), ("1", "1"), ("0", "0"), ("1", "1")])

    def test_missing_log_is_a_one_line_error(self):
        with tempfile.TemporaryDirectory() as tmp:
            with open(os.path.join(tmp, "sweep_meta.json"), "w") as f:
                json.dump({"setting": "x", "downscale": 4, "iterations": 1,
                           "densify_until_iter": 0}, f)
            proc = subprocess.run([sys.executable, os.path.join(HERE, "pareto_plot.py"),
                                   "train-csv", tmp, "--out", os.path.join(tmp, "o.csv")],
                                  capture_output=True, text=True)
            self.assertEqual(proc.returncode, 1)
            self.assertIn("train_log.jsonl: missing", proc.stderr)
            self.assertEqual(len(proc.stderr.strip().splitlines()), 1)
            self.assertFalse(os.path.exists(os.path.join(tmp, "o.csv")))


if __name__ == "__main__":
    unittest.main()
