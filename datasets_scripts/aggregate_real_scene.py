#!/usr/bin/env python3
"""The tables of one real scene from real_scene_tables.sh's output folder (stdlib + json only).

  aggregate_real_scene.py OUT   -> Markdown on stdout

Reads OUT/raw/report.json (the raw model), OUT/times.txt, and for each run OUT/probe/runs/LABEL/
{held,free,eval,table1}.json. Table 1 follows the paper: BER per rendered held-out image (the mean
over views of each view's own BER; where eval drew a random attack several times, --attack_draws,
the cell adds the mean and largest over the draws), for identity / Gaussian noise / dropout / crop, read blind and
as the owner; PSNR and SSIM against the photos, PSNR against the raw model's renders. A single view
is "present" under a key at p <= 1e-6 when at most THRESHOLD of its 48 bits are wrong (the binomial
tail of a fair coin).
"""
import json
import math
import os
import sys

PAPER_LLFF = {"identity": 3.26, "gn:0.01": 4.86, "dropout:0.1": 3.93, "crop:0.1": 4.32}
ATTACKS = ["identity", "gn:0.01", "dropout:0.1", "crop:0.1"]


def present_threshold(bits, p=1e-6):
    """Largest k with P(Binomial(bits, 1/2) <= k) <= p."""
    total, k = 0.0, -1
    while True:
        total += math.comb(bits, k + 1) / 2.0 ** bits
        if total > p:
            return k
        k += 1


def mean(values):
    return sum(values) / len(values) if values else float("nan")


def p90(values):
    ordered = sorted(values)
    return ordered[(9 * len(ordered) + 9) // 10 - 1]


def load(path):
    with open(path) as f:
        return json.load(f)


def row_reading(row, reading):
    """(mean of the views' own BERs, aggregated bit errors) of an eval robustness row in a
    reading (eval's JSON: view_ber holds min / median / mean / p90 / max over the views)."""
    source = row["owner"] if reading == "owner" else row
    return source["view_ber"]["mean"], source["bit_errors"]


def draws_note(row, reading, num_bits):
    """'; N draws: M% (max X%), agg <= E/B, present in K' for a row eval drew more than once
    (--attack_draws: the row itself is the first draw), else ''. K: the draws whose aggregated
    views read 'present' (left out for tables written before eval counted verdicts)."""
    if "draws" not in row:
        return ""
    draws = row["draws"]
    source = draws["owner"] if reading == "owner" else draws
    ber, errors = source["view_ber"], source["bit_errors"]
    note = (f"; {draws['count']} draws: {100 * ber['mean']:.2f}% (max {100 * ber['max']:.2f}%), "
            f"agg <= {errors['max']:.0f}/{num_bits}")
    if "verdicts" in source:
        note += f", present in {source['verdicts']['present']}"
    return note


def main(out):
    runs_dir = os.path.join(out, "probe", "runs")
    raw = load(os.path.join(out, "raw", "report.json"))
    lines = [f"# {os.path.basename(os.path.normpath(out))}: real scene, watergs", ""]
    lines.append(f"Raw model: {raw['num_gaussians']} Gaussians, {raw['iterations']} iterations, "
                 f"held-out PSNR {raw['psnr']:.2f} dB, SSIM {raw['ssim']:.4f} over "
                 f"{raw['num_metric_views']} views (the held-out split), trained in "
                 f"{raw['train_seconds']:.0f} s ({raw['num_threads']} threads, {raw['device']}). "
                 "The paper's 3DGS on LLFF: 24.99 dB, SSIM 0.801 (its Table 2).")
    lines.append("")
    labels = sorted(d for d in os.listdir(runs_dir)
                    if os.path.isfile(os.path.join(runs_dir, d, "table1.json")))
    header = ("| run | reading | " + " | ".join(f"{a} BER/img" for a in ATTACKS) +
              " | PSNR vs photos (raw -> wm) | SSIM | **PSNR vs raw renders** |")
    lines += ["## Table 1: BER per rendered held-out image", "",
              "The paper's LLFF row (its Table 1): " +
              " / ".join(f"{PAPER_LLFF[a]:.2f}%" for a in ATTACKS) +
              " at 21.83 dB against the photos (raw 24.99).", "", header,
              "|" + "---|" * (header.count("|") - 1)]
    single = []
    for label in labels:
        d = os.path.join(runs_dir, label)
        table = load(os.path.join(d, "table1.json"))
        quality = {q["comparison"]: q["mean"] for q in table["quality"]}
        wm_q = quality["watermarked vs ground truth"]
        raw_q = quality.get("raw vs ground truth", {})
        vs_raw = quality["watermarked vs raw renders"]["psnr"]
        rows = {r["attack"]: r for r in table["robustness"] if r["model"] == "watermarked"}
        for reading in ("owner", "blind"):
            cells = []
            for attack in ATTACKS:
                per_image, errors = row_reading(rows[attack], reading)
                bits = table["num_bits"]
                cells.append(f"{100 * per_image:.2f}% ({errors}/{bits} agg)" +
                             draws_note(rows[attack], reading, bits))
            psnr_raw = f"{raw_q['psnr']:.2f}" if "psnr" in raw_q else "n/a"
            lines.append(f"| {label} | {reading} | " + " | ".join(cells) +
                         f" | {psnr_raw} -> {wm_q['psnr']:.2f} | {wm_q['ssim']:.4f} | {vs_raw:.2f} |")
        held, free = load(os.path.join(d, "held.json")), load(os.path.join(d, "free.json"))
        single.append((label, held, free, table["num_bits"]))
    lines += ["", "LPIPS: not computed (the VGG weights are not reachable from the machine that "
              "measured this; `datasets_scripts/download_lpips_weights.sh` fetches them).", ""]
    num_free = sorted({len(free["views"]) for _, _, free, _ in single})
    lines += ["## One view alone (held-out photos' cameras; "
              f"{'/'.join(map(str, num_free))} free viewpoints between cameras)", "",
              "| run | reading | held-out mean / p90 | held-out views 'present' alone at 1e-6 | "
              "free mean / p90 | free 'present' alone |", "|---|---|---|---|---|---|"]
    for label, held, free, bits in single:
        k = present_threshold(bits)
        for reading in ("owner", "blind"):
            row = []
            for source in (held, free):
                j = source["owner"] if reading == "owner" else source
                errors = [v["bit_errors"] for v in j["views"]]
                row.append(f"{100 * mean(errors) / bits:.2f}% / {100 * p90(errors) / bits:.2f}%")
                row.append(f"{sum(e <= k for e in errors)} of {len(errors)}")
            lines.append(f"| {label} | {reading} | " + " | ".join(row) + " |")
    lines += ["", f"'Present' alone: at most {present_threshold(48)} of 48 bits wrong (p <= 1e-6 "
              "under a key, binomial).", ""]
    together = []
    for label, _, _, _ in single:
        path = os.path.join(runs_dir, label, "all_blind.json")
        if os.path.isfile(path):
            j = load(path)
            together.append(f"| {label} | {j['num_views']} | {j['bit_errors']} of {j['num_bits']} | "
                            f"{j['verdict']} |")
    if together:
        lines += ["## Every camera together, read blind (extract without the raw model)", "",
                  "| run | cameras | bits wrong | verdict |", "|---|---|---|---|", *together, ""]
    times_path = os.path.join(out, "times.txt")
    if os.path.exists(times_path):
        lines += ["## Time per stage (2 cores)", "", "| stage | seconds |", "|---|---|"]
        with open(times_path) as f:
            for line in f:
                stage, seconds = line.split()
                lines.append(f"| {stage} | {seconds} |")
    print("\n".join(lines))


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: aggregate_real_scene.py OUT")
    main(sys.argv[1])
