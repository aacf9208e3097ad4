#!/usr/bin/env python3
"""Checks of the README claims check (readme_claims.py, check_claims.py --readme) on the real README
and results/, and on copies with one figure changed (python3 datasets_scripts/test_readme_claims.py)."""

import os
import shutil
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
README = os.path.join(ROOT, "README.md")
sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, HERE)
import readme_claims  # noqa: E402


def read_readme():
    with open(README, encoding="utf-8") as f:
        return f.read()


def changed(figure):
    """The figure one unit (of its integer part) away, printed at the same precision."""
    decimals = len(figure.split(".")[1]) if "." in figure else 0
    return f"{float(figure.replace(',', '')) + 1:.{decimals}f}"


def run_cli(readme, root=ROOT):
    return subprocess.run([sys.executable, os.path.join(HERE, "check_claims.py"), "--readme", readme,
                           "--root", root], capture_output=True, text=True)


class ReadmeClaimsTest(unittest.TestCase):
    def test_every_readme_figure_matches_its_file(self):
        self.assertEqual(readme_claims.check(read_readme(), ROOT), [])

    def test_every_figure_of_every_claim_is_compared(self):
        # Change each figure of each claim alone: the check must name it, so no figure in the manifest
        # is matched without being compared with its file.
        readme = read_readme()
        for claim in readme_claims.CLAIMS:
            if isinstance(claim, readme_claims.Lines):
                continue
            m = claim.pattern().search(readme)
            self.assertIsNotNone(m, claim.phrase)
            for group in range(1, len(m.groups()) + 1):
                altered = readme[:m.start(group)] + changed(m.group(group)) + readme[m.end(group):]
                problems = readme_claims.check(altered, ROOT, [claim])
                self.assertEqual(len(problems), 1, f"{claim.phrase!r}, figure {group}: {problems}")
                self.assertIn("does not match", problems[0])

    def test_cli_passes_on_a_copy_and_fails_in_one_line_on_a_changed_figure(self):
        readme = read_readme()
        cases = [("**38.05 / 38.62 / 38.01 dB**", "**38.05 / 38.72 / 38.01 dB**", "results/mipnerf360_bonsai/tables.md"),
                 ("seeds 0-2, 38.29-38.90", "seeds 0-2, 38.39-38.90", "results/real_llff/fern_252x189_both/tables.md"),
                 ('| 14 of 20 "present" alone', '| 17 of 20 "present" alone', "results/detect_probe/demo_default/results.txt")]
        with tempfile.TemporaryDirectory() as tmp:
            copy = os.path.join(tmp, "README.md")
            shutil.copy(README, copy)
            proc = run_cli(copy)
            self.assertEqual(proc.returncode, 0, proc.stderr)
            self.assertEqual(proc.stderr, "")
            for before, after, path in cases:
                self.assertEqual(readme.count(before), 1, before)
                with open(copy, "w", encoding="utf-8") as f:
                    f.write(readme.replace(before, after))
                proc = run_cli(copy)
                self.assertEqual(proc.returncode, 1, after)
                lines = proc.stderr.strip().splitlines()
                self.assertEqual(len(lines), 1, proc.stderr)
                self.assertIn(after.strip("|* "), lines[0])
                self.assertIn(path, lines[0])

    def test_a_figure_whose_file_is_no_longer_named_beside_it_fails(self):
        readme = read_readme()
        link = "([results](results/real_llff/horns_252x189_draws/))"
        self.assertIn(link, readme)
        problems = readme_claims.check(readme.replace(link, "", 1), ROOT)
        self.assertTrue(problems)
        self.assertTrue(all("results/real_llff/horns_252x189_draws/" in p and "not named beside it" in p
                            for p in problems), problems)

    def test_a_missing_file_or_phrase_fails_naming_the_file(self):
        with tempfile.TemporaryDirectory() as tmp:
            problems = readme_claims.check(read_readme(), tmp)
        self.assertEqual(len(problems), len(readme_claims.CLAIMS))
        self.assertTrue(all("No such file" in p for p in problems), problems[:3])
        claim = readme_claims.Claim("the demo took {} s", readme_claims.grep("results/x.txt", r"(\d+)"))
        (problem,) = readme_claims.check("nothing here", ROOT, [claim])
        self.assertIn("not found in the README", problem)
        self.assertIn("results/x.txt", problem)


class SourcesTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        os.makedirs(os.path.join(self.tmp.name, "results"))
        with open(os.path.join(self.tmp.name, "results", "t.md"), "w") as f:
            f.write("| run | reading | a | PSNR vs photos |\n|---|---|---|---|\n| s0 | owner | 1.50% | 28.12 -> 27.78 |\n"
                    "| s1 | owner | 2.50% | 28.12 -> 27.70 |\n\n| run | reading | c |\n|---|---|---|\n"
                    "| s0 | owner | 9 of 12 |\n")

    def tearDown(self):
        self.tmp.cleanup()

    def values(self, source):
        return source.values(self.tmp.name)

    def test_cells_by_row_keys_and_column_across_tables(self):
        path = "results/t.md"
        self.assertEqual(self.values(readme_claims.cell(path, ("s1", "owner"), "a")), [2.5])
        self.assertEqual(self.values(readme_claims.cell(path, ("s0", "owner"), "PSNR vs photos", 1)), [27.78])
        self.assertEqual(self.values(readme_claims.cell(path, ("s0", "owner"), "c")), [9.0])
        with self.assertRaises(LookupError):
            self.values(readme_claims.cell(path, ("s2", "owner"), "a"))
        a = [readme_claims.cell(path, (r, "owner"), "a") for r in ("s0", "s1")]
        self.assertEqual(self.values(readme_claims.span(*a)), [1.5, 2.5])
        self.assertEqual(self.values(readme_claims.mean(*a)), [2.0])
        loss = readme_claims.losses(path, ("s0", "s1"))
        self.assertAlmostEqual(self.values(loss[1])[0], 0.42)

    def test_json_values_and_every_element_of_a_list(self):
        with open(os.path.join(self.tmp.name, "results", "x.json"), "w") as f:
            f.write('{"owner": {"ber": 0.25, "views": [{"bit_errors": 1}, {"bit_errors": 0}]}}')
        self.assertEqual(self.values(readme_claims.json_at("results/x.json", "owner", "ber")), [0.25])
        self.assertEqual(self.values(readme_claims.json_at("results/x.json", "owner", "views", "*", "bit_errors")),
                         [1.0, 0.0])
        with self.assertRaises(LookupError):
            self.values(readme_claims.json_at("results/x.json", "blind", "ber"))

    def test_a_block_must_be_lines_of_its_file(self):
        with open(os.path.join(self.tmp.name, "results", "log.txt"), "w") as f:
            f.write("+ watergs train\n== summary (12 s)\nraw BER 52.08%\nwm BER 0.00%\n")
        block = readme_claims.Lines("== summary", "results/log.txt")
        readme = "The run (results/log.txt):\n\n```\n== summary (12 s)\nraw BER 52.08%\n```\n"
        self.assertEqual(readme_claims.check(readme, self.tmp.name, [block]), [])
        (problem,) = readme_claims.check(readme.replace("52.08", "50.08"), self.tmp.name, [block])
        self.assertEqual(problem, 'README figure "raw BER 50.08%" is not a line of results/log.txt')

    def test_tolerance_is_the_readmes_rounding(self):
        claim = readme_claims.Claim("at {} dB", readme_claims.cell("results/t.md", ("s0", "owner"), "PSNR", 1))
        self.assertEqual(readme_claims.check("at 27.8 dB", self.tmp.name, [claim]), [
            'README figure "at 27.8 dB": its file results/t.md is not named beside it'])
        self.assertEqual(readme_claims.check("at 27.8 dB (results/t.md)", self.tmp.name, [claim]), [])
        self.assertEqual(readme_claims.check("at 28 dB (results/t.md)", self.tmp.name, [claim]), [])
        (problem,) = readme_claims.check("at 27.7 dB (results/t.md)", self.tmp.name, [claim])
        self.assertIn("README 27.7, file 27.78", problem)


if __name__ == "__main__":
    unittest.main()
