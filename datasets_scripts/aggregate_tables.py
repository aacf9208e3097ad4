#!/usr/bin/env python3
"""Aggregates reproduce_tables.sh runs into the WATER-GS paper's tables (tables.md) and one CSV row per run.

Reads the manifest the shell script writes (one tab-separated line per embedding run: dataset, scene, mask,
distortion layers on/none, message bits, seed, run folder, raw-model folder, downscale) and the eval JSON and
timing files in each run folder. Tables show mean ± sample standard deviation over seeds (per scene) or over
every scene and seed (dataset rows). Both outputs are written atomically. Python standard library only.
"""
import argparse
import csv
import io
import json
import os
import statistics
import sys

ATTACKS = ["identity", "gn:0.01", "dropout:0.1", "crop:0.1"]
ATTACK_TITLES = ["Identity", "GN", "Dropout", "Crop"]
ATTACKED = {"gn:0.01": "gn", "dropout:0.1": "dropout", "crop:0.1": "crop"}
DATASET_TITLES = {"llff": "LLFF", "mipnerf360": "Mip-NeRF 360", "tandt": "Tanks&Temples", "offline": "Offline",
                  "custom": "Custom"}
POSITION_TITLES = {"xyz": "xyz", "f_dc": "h_dc (f_dc)", "f_rest": "h_rest (f_rest)", "ALL": "ALL"}
CSV_FIELDS = ["dataset", "scene", "mask", "distortion_layers", "bits", "seed", "downscale",
              "ber_identity", "ber_gn", "ber_dropout", "ber_crop",
              "agg_ber_identity", "agg_ber_gn", "agg_ber_dropout", "agg_ber_crop",
              "psnr", "ssim", "ms_ssim", "lpips", "psnr_vs_raw",
              "psnr_gn", "psnr_dropout", "psnr_crop",
              "raw_psnr", "raw_ssim", "raw_lpips",
              "gaussians", "train_seconds", "embed_seconds", "eval_seconds"]


def fail(problem):
    sys.exit(f"aggregate_tables.py: error: {problem}")


def read_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        fail(f"{path}: {e}")


def read_seconds(path):
    try:
        with open(path) as f:
            return float(f.read().strip())
    except (OSError, ValueError):
        return None


def quality(report, comparison):
    for q in report["quality"]:
        if q["comparison"] == comparison:
            return q["mean"]
    fail(f"eval report lacks the '{comparison}' comparison")


# BER in percent under a 3D attack: per rendered image (the mean of each view's own BER, as the paper
# measures) and aggregated (the bits of the mean logits over the views, what the verdict reads).
def ber_percent(report, attack, path):
    for r in report["robustness"]:
        if r["model"] == "watermarked" and r["kind"] == "3d" and r["attack"] == attack:
            if "mean" not in r.get("view_ber", {}):
                fail(f"{path}: no per-image BER (written before watergs reported it): rerun this eval step")
            return 100.0 * r["view_ber"]["mean"], 100.0 * r["ber"]
    fail(f"{path}: eval report lacks BER under '{attack}'")


# One run's figures: BER in percent, PSNR in dB, times in seconds.
def load_run(fields):
    dataset, scene, mask, dl, bits, seed, run_dir, raw_dir, downscale = fields
    report_path = os.path.join(run_dir, "eval.json")
    report = read_json(report_path)
    row = {"dataset": dataset, "scene": scene, "mask": mask, "distortion_layers": dl, "bits": int(bits),
           "seed": int(seed), "downscale": int(downscale)}
    for attack in ATTACKS:
        name = attack.split(":")[0]
        row["ber_" + name], row["agg_ber_" + name] = ber_percent(report, attack, report_path)
    wm = quality(report, "watermarked vs ground truth")
    raw = quality(report, "raw vs ground truth")
    row.update(psnr=wm["psnr"], ssim=wm["ssim"], ms_ssim=wm["ms_ssim"], lpips=wm["lpips"],
               psnr_vs_raw=quality(report, "watermarked vs raw renders")["psnr"],
               raw_psnr=raw["psnr"], raw_ssim=raw["ssim"], raw_lpips=raw["lpips"],
               gaussians=report["watermarked_gaussians"])
    for attack, name in ATTACKED.items():
        path = os.path.join(run_dir, f"attacked_{name}.json")
        row["psnr_" + name] = (quality(read_json(path), "watermarked vs ground truth")["psnr"]
                               if os.path.exists(path) else None)
    row["train_seconds"] = read_seconds(os.path.join(raw_dir, "train.seconds"))
    row["embed_seconds"] = read_seconds(os.path.join(run_dir, "embed.seconds"))
    row["eval_seconds"] = read_seconds(os.path.join(run_dir, "eval.seconds"))
    return row


def mean_std(values, digits=2, percent=False):
    values = [v for v in values if v is not None]
    if not values:
        return "n/a"
    suffix = "%" if percent else ""
    mean = statistics.fmean(values)
    if len(values) < 2:
        return f"{mean:.{digits}f}{suffix}"
    return f"{mean:.{digits}f} ± {statistics.stdev(values):.{digits}f}{suffix}"


def select(rows, **conditions):
    return [r for r in rows if all(r[k] == v for k, v in conditions.items())]


# Markdown table: the first two columns (dataset, row name) left-aligned, the figures right-aligned.
def table(header, body):
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(["---"] * 2 + ["---:"] * (len(header) - 2)) + "|"]
    lines += ["| " + " | ".join(cells) + " |" for cells in body]
    return "\n".join(lines) + "\n"


def datasets_in(rows):
    return list(dict.fromkeys(r["dataset"] for r in rows))


def scenes_in(rows, dataset):
    return list(dict.fromkeys(r["scene"] for r in rows if r["dataset"] == dataset))


def robustness_table(rows, main):
    body = []
    for dataset in datasets_in(rows):
        runs = select(rows, dataset=dataset, mask="ALL", distortion_layers="on", bits=main)
        for scene in scenes_in(runs, dataset):
            scene_runs = select(runs, scene=scene)
            body.append([DATASET_TITLES.get(dataset, dataset), scene] +
                        [mean_std([r["ber_" + a.split(":")[0]] for r in scene_runs]) for a in ATTACKS])
        body.append([f"**{DATASET_TITLES.get(dataset, dataset)}**", "**mean**"] +
                    [mean_std([r["ber_" + a.split(":")[0]] for r in runs]) for a in ATTACKS])
    return table(["Dataset", "Scene"] + [t + " BER per image (%)" for t in ATTACK_TITLES], body)


def ablation_dl_table(rows, main):
    body = []
    for dataset in datasets_in(rows):
        for dl, title in [("none", "Ours w/o DL"), ("on", "Ours")]:
            runs = select(rows, dataset=dataset, mask="ALL", distortion_layers=dl, bits=main)
            cells = [DATASET_TITLES.get(dataset, dataset), title]
            for attack in ATTACKS:
                name = attack.split(":")[0]
                cells.append(mean_std([r["ber_" + name] for r in runs]))
                cells.append(mean_std([r["psnr" if name == "identity" else "psnr_" + name] for r in runs]))
            body.append(cells)
    header = ["Dataset", "Method"]
    for title in ATTACK_TITLES:
        header += [f"{title} BER per image (%)", f"{title} PSNR"]
    return table(header, body)


def quality_cells(runs):
    return [mean_std([r["ber_identity"] for r in runs]), mean_std([r["psnr"] for r in runs]),
            mean_std([r["ssim"] for r in runs], 3), mean_std([r["lpips"] for r in runs], 3)]


def positions_table(rows, main):
    body = []
    for dataset in datasets_in(rows):
        for mask in ["xyz", "f_dc", "f_rest", "ALL"]:
            runs = select(rows, dataset=dataset, mask=mask, distortion_layers="none", bits=main)
            if runs:
                body.append([DATASET_TITLES.get(dataset, dataset), POSITION_TITLES[mask]] + quality_cells(runs))
    return table(["Dataset", "Embedding positions", "BER per image (%)", "PSNR", "SSIM", "LPIPS"], body)


def lengths_table(rows):
    body = []
    for dataset in datasets_in(rows):
        runs = select(rows, dataset=dataset, mask="ALL", distortion_layers="on")
        # The raw model is the same for every run of a scene: one value per scene.
        raw = {r["scene"]: r for r in runs}.values()
        body.append([DATASET_TITLES.get(dataset, dataset), "0 bit (raw 3DGS)", "n/a",
                     mean_std([r["raw_psnr"] for r in raw]), mean_std([r["raw_ssim"] for r in raw], 3),
                     mean_std([r["raw_lpips"] for r in raw], 3)])
        for bits in sorted({r["bits"] for r in runs}):
            body.append([DATASET_TITLES.get(dataset, dataset), f"{bits} bits"] + quality_cells(select(runs, bits=bits)))
    return table(["Dataset", "Bit number", "BER per image (%)", "PSNR", "SSIM", "LPIPS"], body)


def timing_table(rows, main):
    body = []
    for dataset in datasets_in(rows):
        runs = select(rows, dataset=dataset)
        train = {r["scene"]: r["train_seconds"] for r in runs}.values()
        body.append([DATASET_TITLES.get(dataset, dataset), "3DGS (train)", mean_std(train, 1)])
        for dl, title in [("none", "WATER-GS w/o DL (embed)"), ("on", "WATER-GS (embed)")]:
            body.append([DATASET_TITLES.get(dataset, dataset), title, mean_std(
                [r["embed_seconds"] for r in select(runs, mask="ALL", distortion_layers=dl, bits=main)], 1)])
        body.append([DATASET_TITLES.get(dataset, dataset), "eval (per run)",
                     mean_std([r["eval_seconds"] for r in runs], 1)])
    return table(["Dataset", "Step", "Wall time (s)"], body)


def write_atomic(path, text):
    tmp = path + ".tmp"
    with open(tmp, "w", newline="") as f:
        f.write(text)
    os.replace(tmp, path)


def csv_text(rows):
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=CSV_FIELDS, lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({k: ("" if r[k] is None else (f"{r[k]:.6g}" if isinstance(r[k], float) else r[k]))
                         for k in CSV_FIELDS})
    return out.getvalue()


def markdown(rows, main, settings, note):
    parts = ["# WATER-GS reproduction tables\n"]
    if note:
        parts.append(note + "\n")
    parts.append(f"Settings: {settings}. Decoder lengths: {sorted({r['bits'] for r in rows})} "
                 f"(robustness and ablations use {main} bits). Held-out views: every 8th image. "
                 "Cells: mean ± sample std over seeds (scene rows) or over every scene and seed (dataset rows); "
                 "BER in percent per rendered held-out image (each view decoded alone, as the paper measures; "
                 "the aggregated BER of the mean logits is in results.csv as agg_ber_*), PSNR in dB against "
                 "ground truth. LPIPS is n/a when its weights are absent.\n")
    parts.append("## Robustness under 3D distortions (paper Table 1, WATER-GS with distortion layers)\n")
    parts.append(robustness_table(rows, main))
    parts.append("\n## Ablation on the 3D distortion layers (BER and PSNR of the distorted model)\n")
    parts.append(ablation_dl_table(rows, main))
    parts.append("\n## Embedding positions (without distortion layers, as in the paper)\n")
    parts.append(positions_table(rows, main))
    parts.append("\n## Message lengths (with distortion layers; BER without distortion)\n")
    parts.append(lengths_table(rows))
    parts.append("\n## Wall time per run\n")
    parts.append(timing_table(rows, main))
    return "\n".join(parts)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--manifest", required=True)
    parser.add_argument("--output_dir", required=True)
    parser.add_argument("--main_length", type=int, required=True)
    parser.add_argument("--settings", default="")
    parser.add_argument("--note", default="")
    args = parser.parse_args()
    with open(args.manifest) as f:
        lines = [line.rstrip("\n").split("\t") for line in f if line.strip()]
    if not lines:
        fail(f"{args.manifest}: no runs")
    for fields in lines:
        if len(fields) != 9:
            fail(f"{args.manifest}: malformed line {fields}")
    rows = [load_run(fields) for fields in lines]
    write_atomic(os.path.join(args.output_dir, "results.csv"), csv_text(rows))
    write_atomic(os.path.join(args.output_dir, "tables.md"), markdown(rows, args.main_length, args.settings, args.note))


if __name__ == "__main__":
    main()
