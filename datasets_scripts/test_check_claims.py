#!/usr/bin/env python3
"""Checks of check_claims.py on small hand-made results (python3 datasets_scripts/test_check_claims.py)."""

import csv
import json
import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, HERE)
import check_claims  # noqa: E402


def run(mask, layers, bits, seed, ber_identity, ber_gn, scene="a"):
    return {"dataset": "offline", "scene": scene, "mask": mask, "distortion_layers": layers, "bits": bits,
            "seed": str(seed), "ber_identity": ber_identity, "ber_gn": ber_gn}


def paper_like_runs():
    """Two scenes x 3 seeds shaped like the paper's tables (every claim should hold)."""
    rows = []
    for scene in ("a", "b"):
        for seed in range(3):
            rows.append(run("ALL", "on", 48, seed, 3.0 + seed, 5.0, scene))
            rows.append(run("ALL", "none", 48, seed, 4.0, 25.0 - seed, scene))
            rows.append(run("xyz", "none", 48, seed, 39.0, 40.0, scene))
            rows.append(run("f_dc", "none", 48, seed, 13.0, 20.0, scene))
            rows.append(run("f_rest", "none", 48, seed, 10.0, 18.0, scene))
            rows.append(run("ALL", "on", 8, seed, 0.0, 2.0, scene))
    return rows


def verdicts(markdown):
    """Verdict column of the claims table, in row order."""
    return [line.split(" | ")[3] for line in markdown.splitlines() if line.startswith("| ") and "---" not in
            line and not line.startswith("| Claim")]


class ClaimsTest(unittest.TestCase):
    def test_paper_like_runs_hold(self):
        md = check_claims.claims_markdown(paper_like_runs(), [("HiDDeN + 3DGS", 48.0)], 48)
        self.assertIn("-> yes", md)
        self.assertEqual(verdicts(md), ["holds"] * 4)

    def test_chance_level_runs_are_not_testable(self):
        # 50% +- a little everywhere: the claims would "hold" by accident (lengths within 10 points).
        rows = [dict(r, ber_identity=50.0 + (i % 3) - 1, ber_gn=50.0) for i, r in enumerate(paper_like_runs())]
        md = check_claims.claims_markdown(rows, [("HiDDeN + 3DGS", 50.0)], 48)
        self.assertIn("-> no", md)
        self.assertEqual(verdicts(md), ["not testable"] * 4)

    def test_each_claim_can_fail(self):
        rows = paper_like_runs()
        for r in rows:
            if r["mask"] == "ALL" and r["distortion_layers"] == "none":
                r["ber_gn"] = 6.0  # layers cut GN BER by only 1 point
                r["ber_identity"] = 12.0  # f_rest (10%) now beats ALL
            if r["bits"] == 8:
                r["ber_identity"] = 30.0  # lengths 8 and 48 now 26 points apart
        md = check_claims.claims_markdown(rows, [("CONCAT + 3DGS", 20.0)], 48)
        self.assertIn("-> yes", md)
        self.assertEqual(verdicts(md), ["does not hold"] * 4)

    def test_missing_runs_are_not_testable(self):
        rows = [r for r in paper_like_runs() if r["mask"] == "ALL" and r["distortion_layers"] == "on"
                and r["bits"] == 48]
        md = check_claims.claims_markdown(rows, [], 48)
        self.assertEqual(verdicts(md), ["not testable"] * 3)

    def test_binomial_tail_matches_direct_sum(self):
        from math import comb
        for n, k in [(8, 0), (8, 3), (48, 20), (48, 24)]:
            direct = sum(comb(n, i) for i in range(k + 1)) / 2 ** n
            self.assertAlmostEqual(check_claims.binomial_tail(k, n), direct, places=12)

    def test_cli_reads_csv_and_both_baseline_formats(self):
        with tempfile.TemporaryDirectory() as tmp:
            results = os.path.join(tmp, "results.csv")
            with open(results, "w", newline="") as f:
                writer = csv.DictWriter(f, fieldnames=list(paper_like_runs()[0]) + ["psnr"])
                writer.writeheader()
                for r in paper_like_runs():
                    writer.writerow(dict(r, psnr=30.0))
            extract = os.path.join(tmp, "extract.json")
            with open(extract, "w") as f:
                json.dump({"ber": 0.47, "num_bits": 48}, f)
            evaluation = os.path.join(tmp, "eval.json")
            with open(evaluation, "w") as f:
                json.dump({"robustness": [{"model": "watermarked", "kind": "3d", "attack": "identity",
                                           "ber": 0.2}]}, f)
            out = os.path.join(tmp, "claims.md")
            subprocess.run([sys.executable, os.path.join(HERE, "check_claims.py"), "--results", results,
                            "--output", out, "--baseline", f"HiDDeN + 3DGS={extract}",
                            "--baseline", f"CONCAT + 3DGS={evaluation}"], check=True)
            with open(out) as f:
                md = f.read()
            self.assertIn("47.00%", md)
            self.assertEqual(verdicts(md), ["holds", "does not hold", "holds", "holds", "holds"])

    def test_cli_errors_name_the_file(self):
        with tempfile.TemporaryDirectory() as tmp:
            bad = os.path.join(tmp, "results.csv")
            with open(bad, "w") as f:
                f.write("a,b\n1,2\n")
            out = os.path.join(tmp, "claims.md")
            proc = subprocess.run([sys.executable, os.path.join(HERE, "check_claims.py"), "--results", bad,
                                   "--output", out], capture_output=True, text=True)
            self.assertNotEqual(proc.returncode, 0)
            self.assertIn(bad, proc.stderr)
            self.assertEqual(len(proc.stderr.strip().splitlines()), 1)
            self.assertFalse(os.path.exists(out))


if __name__ == "__main__":
    unittest.main()
