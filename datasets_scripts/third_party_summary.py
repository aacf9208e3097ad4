#!/usr/bin/env python3
"""The figures of one third_party_splat.sh run: third_party_summary.py OUT SEED.

Appends to OUT/summary.txt and prints: the owner's reading of each held-out view alone (bits
wrong, and how many views read 'present' alone: at most 7 of 48 wrong, p <= 1e-6), eval's
held-out PSNR with the splat placed and taken as it is, and the placement line embed printed.
"""
import json
import os
import sys


def quality(path):
    return "; ".join(f"{q['comparison']} {q['mean']['psnr']:.2f} dB"
                     for q in json.load(open(path))["quality"])


def main(out, seed):
    owner = json.load(open(f"{out}/extract_owner_s{seed}.json"))["owner"]
    errors = [v["bit_errors"] for v in owner["views"]]
    bits = owner["num_bits"]
    embed_log = f"{out}/embed_s{seed}.log"
    placed = []
    if os.path.exists(embed_log):
        placed = [line for line in open(embed_log).read().splitlines()
                  if "another frame" in line or "matches the workspace" in line]
    lines = [
        f"seed {seed}: owner's reading, each held-out view alone: mean BER "
        f"{100 * sum(errors) / (bits * len(errors)):.2f}% "
        f"({', '.join(map(str, errors))} of {bits} wrong; "
        f"{sum(e <= 7 for e in errors)} of {len(errors)} 'present' alone)",
        f"seed {seed}: held-out PSNR, placed: {quality(f'{out}/eval_s{seed}.json')}",
        f"seed {seed}: held-out PSNR, --align off: "
        f"{quality(f'{out}/eval_align_off_s{seed}.json')}",
    ] + [f"seed {seed}: {line}" for line in placed]
    with open(f"{out}/summary.txt", "a") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
