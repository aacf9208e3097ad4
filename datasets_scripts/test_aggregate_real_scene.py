#!/usr/bin/env python3
"""Checks of aggregate_real_scene.py on a hand-made output folder: Table 1's cells are the mean of
the per-view BERs (not the aggregated read) in each reading, the "present alone" counts use the
binomial threshold, and the PSNR columns come from the right comparison
(python3 datasets_scripts/test_aggregate_real_scene.py)."""

import json
import math
import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True
sys.path.insert(0, HERE)
import aggregate_real_scene  # noqa: E402


def write(path, data):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        json.dump(data, f)


def stats(views):
    """eval's view_ber: statistics over the views' own BERs."""
    return {"min": min(views), "max": max(views), "mean": sum(views) / len(views),
            "median": sorted(views)[len(views) // 2], "p90": max(views)}


def robustness_row(attack, blind_views, owner_views):
    return {"model": "watermarked", "attack": attack, "view_ber": stats(blind_views), "bit_errors": 9,
            "ber": 9 / 48, "owner": {"view_ber": stats(owner_views), "bit_errors": 1, "ber": 1 / 48}}


class AggregateRealScene(unittest.TestCase):
    def test_threshold_is_the_binomial_tail(self):
        def tail(k):
            return sum(math.comb(48, i) for i in range(k + 1)) / 2.0 ** 48
        k = aggregate_real_scene.present_threshold(48)
        self.assertLessEqual(tail(k), 1e-6)
        self.assertGreater(tail(k + 1), 1e-6)
        self.assertEqual(k, 7)

    def test_tables_from_a_folder(self):
        with tempfile.TemporaryDirectory() as out:
            write(f"{out}/raw/report.json", {"num_gaussians": 1000, "iterations": 7000, "psnr": 22.5,
                                             "ssim": 0.6, "num_metric_views": 2, "train_seconds": 90,
                                             "num_threads": 2, "device": "cpu"})
            run = f"{out}/probe/runs/owner_seed0"
            rows = [robustness_row(a, [0.5, 0.25], [0.0, 0.125])
                    for a in ("identity", "gn:0.01", "dropout:0.1", "crop:0.1")]
            spread = {"mean": 0.03125, "min": 0.0, "max": 0.0625}
            rows[3]["draws"] = {"count": 4, "view_ber": spread, "bit_errors": spread,
                                "owner": {"view_ber": spread,
                                          "bit_errors": {"mean": 1.5, "min": 0, "max": 3},
                                          "verdicts": {"present": 3, "inconclusive": 1,
                                                       "absent": 0}}}
            rows.append({"model": "raw", "attack": "identity", "view_ber": stats([0.9, 0.9]),
                         "bit_errors": 30, "owner": {"view_ber": stats([1.0, 1.0]), "bit_errors": 48}})
            write(f"{run}/table1.json", {"num_bits": 48, "robustness": rows, "quality": [
                {"comparison": "watermarked vs ground truth", "mean": {"psnr": 21.5, "ssim": 0.55}},
                {"comparison": "raw vs ground truth", "mean": {"psnr": 22.0, "ssim": 0.6}},
                {"comparison": "watermarked vs raw renders", "mean": {"psnr": 36.25, "ssim": 0.99}}]})
            views = {"num_bits": 48, "views": [{"bit_errors": 7}, {"bit_errors": 8}],
                     "owner": {"num_bits": 48, "views": [{"bit_errors": 0}, {"bit_errors": 2}]}}
            write(f"{run}/held.json", views)
            write(f"{run}/free.json", views)
            with open(f"{out}/times.txt", "w") as f:
                f.write("train 90\n")
            text = subprocess.run([sys.executable, f"{HERE}/aggregate_real_scene.py", out],
                                  check=True, capture_output=True, text=True).stdout
        owner = next(l for l in text.splitlines() if l.startswith("| owner_seed0 | owner |"))
        blind = next(l for l in text.splitlines() if l.startswith("| owner_seed0 | blind |"))
        # Mean of the views' BERs: owner (0 + 12.5) / 2, blind (50 + 25) / 2.
        self.assertIn("6.25% (1/48 agg)", owner)
        # The crop row was drawn 4 times: its first draw, then the draws' mean and worst and
        # how many draws read 'present' (a table from before verdict counts says nothing).
        self.assertIn("6.25% (1/48 agg); 4 draws: 3.12% (max 6.25%), agg <= 3/48, present in 3",
                      owner)
        self.assertEqual(owner.count("draws"), 1)
        self.assertIn("4 draws: 3.12% (max 6.25%), agg <= 0/48 |", blind)
        self.assertIn("37.50% (9/48 agg)", blind)
        self.assertIn("22.00 -> 21.50", owner)
        self.assertIn("| 36.25 |", owner)
        single_owner = [l for l in text.splitlines() if l.startswith("| owner_seed0 | owner |")][1]
        single_blind = [l for l in text.splitlines() if l.startswith("| owner_seed0 | blind |")][1]
        self.assertIn("| 2 of 2 |", single_owner)  # 0 and 2 errors
        self.assertIn("| 1 of 2 |", single_blind)  # 7 passes, 8 does not
        self.assertIn("| train | 90 |", text)


if __name__ == "__main__":
    unittest.main()
