#!/usr/bin/env python3
"""Accuracy-vs-time tables for the watergs sweeps: collects the runs of
sweep_training_time.sh / sweep_embedding_time.sh into one CSV, marks the Pareto
front (least time, best accuracy) and writes a gnuplot script for the PNG.

Python 3 standard library only. Every output is written to a temporary file in
the same folder and renamed, so an interrupted run never leaves half a file.

Subcommands:
  train-csv RUN_DIR... --out CSV     rows from each RUN_DIR/train_log.jsonl + sweep_meta.json;
                                     front per downscale (PSNR is against that resolution),
                                     over all rows (pareto) and over run ends (pareto_final)
  embed-csv POINT_JSON... --out CSV  rows from the per-point JSON the embedding sweep writes
  plot-train CSV --png PNG           PSNR against training time, front marked
  plot-embed CSV --png PNG           BER and PSNR against embedding time, fronts marked
  front CSV --x COL --y COL [--maximize]  prints the front rows of any CSV (for checks)
"""

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile


def fail(message):
    """One-line error on stderr, exit status 1."""
    sys.stderr.write("pareto_plot: " + message + "\n")
    sys.exit(1)


def atomic_write(path, text):
    """Writes text to path through a temporary file in the same folder."""
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp_", suffix=os.path.basename(path))
    try:
        with os.fdopen(fd, "w", newline="") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def finite(value):
    """value as a float, or None when missing, empty or not finite."""
    if value is None or value == "":
        return None
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def pareto_front(points, maximize_y):
    """Indices of the non-dominated points of [(x, y)], x minimised and y
    minimised (or maximised). A point is dominated when another is no worse in
    both and better in one; points with a missing coordinate are never on the
    front. Equal points are all kept."""
    sign = -1.0 if maximize_y else 1.0
    valid = [(x, sign * y, i) for i, (x, y) in enumerate(points)
             if finite(x) is not None and finite(y) is not None]
    valid.sort()
    front = []
    best_y = math.inf
    best_x = None
    for x, y, i in valid:
        if y < best_y:
            front.append(i)
            best_y, best_x = y, x
        elif y == best_y and x == best_x:
            front.append(i)
    return sorted(front)


def pareto_front_nd(rows, objectives):
    """Indices of the rows not dominated in every objective: objectives is a
    list of (key, maximize). Rows with a missing value are never on it."""
    vectors = []
    for i, row in enumerate(rows):
        v = [finite(row.get(k)) for k, _ in objectives]
        if all(x is not None for x in v):
            vectors.append((i, [(-x if mx else x) for x, (_, mx) in zip(v, objectives)]))
    front = []
    for i, a in vectors:
        dominated = any(all(bj <= aj for aj, bj in zip(a, b)) and any(bj < aj for aj, bj in zip(a, b))
                        for _, b in vectors)
        if not dominated:
            front.append(i)
    return front


def csv_text(fields, rows):
    """rows (dicts) as CSV text with the given column order."""
    import io
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=fields, lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in fields})
    return buf.getvalue()


def read_csv(path):
    if not os.path.isfile(path):
        fail(path + ": no such CSV file")
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def load_json(path):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        fail("%s: %s" % (path, e))


TRAIN_FIELDS = ["setting", "downscale", "max_iterations", "densify_until_iter", "iteration",
                "train_seconds", "test_psnr", "test_ssim", "num_gaussians", "run_wall_seconds",
                "load_avg_after", "final", "pareto", "pareto_final"]


def train_rows(run_dir):
    """One row per logged test iteration of a training run."""
    meta = load_json(os.path.join(run_dir, "sweep_meta.json"))
    log = os.path.join(run_dir, "train_log.jsonl")
    if not os.path.isfile(log):
        fail(log + ": missing (did the train run finish?)")
    rows = []
    with open(log) as f:
        for number, line in enumerate(f, 1):
            line = line.strip()
            if not line:
                continue
            try:
                j = json.loads(line)
            except ValueError:
                fail("%s:%d: not a JSON line" % (log, number))
            if "test_psnr" not in j:
                continue
            rows.append({
                "setting": meta["setting"],
                "downscale": meta["downscale"],
                "max_iterations": meta["iterations"],
                "densify_until_iter": meta["densify_until_iter"],
                "iteration": j["iteration"],
                "train_seconds": j["seconds"],
                "test_psnr": "%.4f" % j["test_psnr"],
                "test_ssim": "%.5f" % j["test_ssim"],
                "num_gaussians": j["num_gaussians"],
                "run_wall_seconds": meta.get("wall_seconds"),
                "load_avg_after": meta.get("load_avg_after"),
                "final": 1 if j["iteration"] == meta["iterations"] else 0,
            })
    if not rows:
        fail(log + ": no held-out test lines (train with --split train and --test_iterations)")
    return rows


def cmd_train_csv(args):
    rows = []
    for run_dir in args.runs:
        rows += train_rows(run_dir)
    # PSNR is measured against ground truth at each run's own resolution, so a
    # front only compares runs of one downscale (one output resolution).
    front = set()
    for ds in sorted({r["downscale"] for r in rows}):
        group = [i for i, r in enumerate(rows) if r["downscale"] == ds]
        points = [(finite(rows[i]["train_seconds"]), finite(rows[i]["test_psnr"])) for i in group]
        front |= {group[k] for k in pareto_front(points, maximize_y=True)}
    # The same among run ends only: what a run of that many iterations delivers.
    front_final = set()
    for ds in sorted({r["downscale"] for r in rows}):
        group = [i for i, r in enumerate(rows) if r["downscale"] == ds and r["final"] == 1]
        points = [(finite(rows[i]["train_seconds"]), finite(rows[i]["test_psnr"])) for i in group]
        front_final |= {group[k] for k in pareto_front(points, maximize_y=True)}
    for i, r in enumerate(rows):
        r["pareto"] = 1 if i in front else 0
        r["pareto_final"] = 1 if i in front_final else 0
    atomic_write(args.out, csv_text(TRAIN_FIELDS, rows))
    print("pareto_plot: %d rows, %d on the per-resolution fronts, %d run ends on theirs -> %s" %
          (len(rows), len(front), len(front_final), args.out))


EMBED_FIELDS = ["setting", "iterations", "crop_size", "distortions", "num_bits", "embed_seconds",
                "iterations_run", "gaussians", "psnr_vs_raw", "ssim_vs_raw", "psnr_vs_gt",
                "raw_psnr_vs_gt", "ber_identity", "ber_gn", "ber_dropout", "ber_crop", "ber_mean",
                "ber_raw", "load_avg_after", "pareto_ber", "pareto_psnr", "pareto_all"]

ATTACK_COLUMNS = {"identity": "ber_identity", "gn": "ber_gn", "dropout": "ber_dropout",
                  "crop": "ber_crop"}


def embed_row(path):
    """One row from a point JSON: {setting, iterations, crop_size, distortions,
    num_bits, embed_seconds, iterations_run, eval: <watergs eval JSON>}."""
    p = load_json(path)
    ev = p.get("eval") or {}
    row = {k: p.get(k) for k in ["setting", "iterations", "crop_size", "distortions", "num_bits",
                                 "embed_seconds", "iterations_run", "load_avg_after"]}
    row["gaussians"] = ev.get("watermarked_gaussians")
    quality = {q.get("comparison", ""): q.get("mean", {}) for q in ev.get("quality", [])}

    def pick(prefix, key):
        for name, mean in quality.items():
            if name.startswith(prefix):
                return finite(mean.get(key))
        return None
    row["psnr_vs_raw"] = pick("watermarked vs raw", "psnr")
    row["ssim_vs_raw"] = pick("watermarked vs raw", "ssim")
    row["psnr_vs_gt"] = pick("watermarked vs ground", "psnr")
    row["raw_psnr_vs_gt"] = pick("raw vs ground", "psnr")
    bers = []
    for r in ev.get("robustness", []):
        attack = str(r.get("attack", ""))
        name = attack.split(":")[0]
        if r.get("model") == "raw":
            row["ber_raw"] = finite(r.get("ber"))
        elif name in ATTACK_COLUMNS and r.get("kind", "3d") == "3d":
            row[ATTACK_COLUMNS[name]] = finite(r.get("ber"))
            bers.append(finite(r.get("ber")))
    bers = [b for b in bers if b is not None]
    row["ber_mean"] = sum(bers) / len(bers) if bers else None
    for k in ["psnr_vs_raw", "ssim_vs_raw", "psnr_vs_gt", "raw_psnr_vs_gt", "ber_identity",
              "ber_gn", "ber_dropout", "ber_crop", "ber_mean", "ber_raw"]:
        if row.get(k) is not None:
            row[k] = "%.4f" % row[k]
    return row


def cmd_embed_csv(args):
    rows = [embed_row(p) for p in args.points]
    t = [finite(r["embed_seconds"]) for r in rows]
    front_ber = set(pareto_front(list(zip(t, [finite(r["ber_mean"]) for r in rows])), False))
    front_psnr = set(pareto_front(list(zip(t, [finite(r["psnr_vs_raw"]) for r in rows])), True))
    front_all = set(pareto_front_nd(rows, [("embed_seconds", False), ("ber_mean", False),
                                           ("psnr_vs_raw", True)]))
    for i, r in enumerate(rows):
        r["pareto_ber"] = 1 if i in front_ber else 0
        r["pareto_psnr"] = 1 if i in front_psnr else 0
        r["pareto_all"] = 1 if i in front_all else 0
    atomic_write(args.out, csv_text(EMBED_FIELDS, rows))
    print("pareto_plot: %d points; fronts: BER %d, PSNR %d, all three %d -> %s" %
          (len(rows), len(front_ber), len(front_psnr), len(front_all), args.out))


def data_block(rows, columns):
    """Whitespace-separated data lines for gnuplot (missing values as NaN)."""
    lines = []
    for r in rows:
        vals = []
        for c in columns:
            v = r.get(c)
            if isinstance(v, str) and c in ("setting", "label"):
                vals.append('"%s"' % v.replace('"', "'"))
            else:
                x = finite(v)
                vals.append("NaN" if x is None else repr(x))
        lines.append(" ".join(vals))
    return "\n".join(lines)


def run_gnuplot(script, png):
    """Runs gnuplot on script, writing png atomically."""
    folder = os.path.dirname(os.path.abspath(png))
    os.makedirs(folder, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp_", suffix=".png")
    os.close(fd)
    script = script.replace("@PNG@", tmp.replace('"', '\\"'))
    try:
        proc = subprocess.run(["gnuplot"], input=script, text=True, capture_output=True)
    except FileNotFoundError:
        os.unlink(tmp)
        fail("gnuplot not found (apt-get install gnuplot-nox, see scripts/install_deps.sh)")
    if proc.returncode != 0 or os.path.getsize(tmp) == 0:
        os.unlink(tmp)
        fail("gnuplot failed: " + proc.stderr.strip().replace("\n", " | "))
    os.replace(tmp, png)
    # The script beside the PNG, so the plot can be restyled without rerunning.
    atomic_write(os.path.splitext(png)[0] + ".gp", script.replace(tmp, png))


def terminal():
    """pngcairo when this gnuplot has it, otherwise the libgd png terminal."""
    proc = subprocess.run(["gnuplot", "-e", "set terminal"], capture_output=True, text=True)
    return "pngcairo" if "pngcairo" in (proc.stdout + proc.stderr) else "png"


def cmd_plot_train(args):
    rows = read_csv(args.csv)
    # One panel per downscale: PSNR is only comparable at one resolution.
    downscales = sorted({r["downscale"] for r in rows}, key=lambda d: -int(d))
    blocks, panels = [], []
    for ds in downscales:
        sub = [r for r in rows if r["downscale"] == ds]
        settings = []
        for r in sub:
            if r["setting"] not in settings:
                settings.append(r["setting"])
        plots = []
        for s in settings:
            name = "$S%d" % len(blocks)
            blocks.append("%s << EOD\n%s\nEOD" % (name, data_block(
                [r for r in sub if r["setting"] == s], ["train_seconds", "test_psnr", "iteration"])))
            # Dashed: density control stopped early; dotted: none.
            dash = 3 if "no densification" in s else 2 if "densify until" in s else 1
            plots.append("%s using 1:2 with linespoints pt 7 ps 0.6 lw 1.5 dt %d title \"%s\"" %
                         (name, dash, s))
        ends = "$E%s" % ds
        blocks.append("%s << EOD\n%s\nEOD" % (ends, data_block(
            [r for r in sub if r.get("final") == "1"], ["train_seconds", "test_psnr", "iteration"])))
        front = "$F%s" % ds
        blocks.append("%s << EOD\n%s\nEOD" % (front, data_block(
            sorted((r for r in sub if r["pareto"] == "1"), key=lambda r: finite(r["train_seconds"])),
            ["train_seconds", "test_psnr", "iteration"])))
        plots.append("%s using 1:2 with points pt 5 ps 1.1 lc rgb \"black\" title \"end of a run\"" % ends)
        plots.append("%s using 1:2 with lines dt 2 lw 1 lc rgb \"black\" notitle" % front)
        plots.append("%s using 1:2 with points pt 6 ps 2.2 lw 2 lc rgb \"red\" "
                     "title \"Pareto front (this resolution)\"" % front)
        plots.append("%s using 1:2:(sprintf(\"%%d\", $3)) with labels offset 0,1.1 font \",8\" "
                     "notitle" % front)
        panels.append("set title \"1/%s resolution (held-out PSNR against ground truth at 1/%s)\"\n"
                      "plot %s" % (ds, ds, ", \\\n  ".join(plots)))
    script = "\n".join(blocks) + """
set terminal %s size 1000,%d font ",10" noenhanced
set output "@PNG@"
set multiplot layout %d,1 title "%s"
set xlabel "training wall time (s, training steps only; threads as in commands.txt)"
set ylabel "held-out PSNR (dB)"
set grid
set key outside right
%s
unset multiplot
""" % (terminal(), 120 + 420 * len(panels), len(panels), args.title, "\n".join(panels))
    run_gnuplot(script, args.png)
    print("pareto_plot: wrote " + args.png)


def cmd_plot_embed(args):
    rows = read_csv(args.csv)
    cols = ["embed_seconds", "ber_mean", "psnr_vs_raw", "ber_identity", "ber_gn", "ber_dropout",
            "ber_crop"]
    lengths = {r["num_bits"] for r in rows}
    labelled = []
    for r in rows:
        r = dict(r)
        # Short point labels: D/- = distortion layers on/off, c = crop side, it = iterations.
        r["label"] = "%s c%s %sit%s" % ("D" if r["distortions"] == "on" else "-",
                                        r["crop_size"] if r["crop_size"] != "0" else "frame",
                                        r["iterations"],
                                        " %sb" % r["num_bits"] if len(lengths) > 1 else "")
        labelled.append(r)
    bers = [finite(r.get(c)) for r in rows for c in cols[3:] + ["ber_mean"]]
    ber_top = max([0.55] + [b + 0.05 for b in bers if b is not None])
    all_block = "$A << EOD\n%s\nEOD" % data_block(labelled, cols + ["label"])
    fb = sorted((r for r in labelled if r["pareto_ber"] == "1"),
                key=lambda r: finite(r["embed_seconds"]))
    fp = sorted((r for r in labelled if r["pareto_psnr"] == "1"),
                key=lambda r: finite(r["embed_seconds"]))
    script = "\n".join([all_block,
                        "$FB << EOD\n%s\nEOD" % data_block(fb, cols),
                        "$FP << EOD\n%s\nEOD" % data_block(fp, cols)]) + """
set terminal %s size 1000,900 font ",10" noenhanced
set output "@PNG@"
set multiplot layout 2,1 title "%s"
set grid
set xlabel "embedding wall time (s, whole embed command; threads as in commands.txt)"
set ylabel "BER (fraction of bits wrong)"
set key outside right
set yrange [0:%.2f]
plot $A using 1:4 with points pt 1 ps 1.2 title "identity", \\
  $A using 1:5 with points pt 2 ps 1.2 title "gn:0.01", \\
  $A using 1:6 with points pt 4 ps 1.2 title "dropout:0.1", \\
  $A using 1:7 with points pt 8 ps 1.2 title "crop:0.1", \\
  $A using 1:2 with points pt 7 ps 1.3 lc rgb "black" title "mean of the four", \\
  $FB using 1:2 with linespoints pt 6 ps 2.4 lw 2 lc rgb "red" title "Pareto front (mean BER)", \\
  0.5 with lines dt 2 lc rgb "gray" title "chance"
set ylabel "PSNR vs raw renders (dB)"
set title "points: D = distortion layers on, - = off; c = crop side (frame = whole views); it = iterations" font ",9"
set yrange [*:*]
plot $A using 1:3 with points pt 7 ps 1.3 lc rgb "black" title "points", \\
  $A using 1:3:8 with labels offset 0,0.8 font ",8" notitle, \\
  $FP using 1:3 with linespoints pt 6 ps 2.4 lw 2 lc rgb "blue" title "Pareto front (PSNR)"
unset multiplot
""" % (terminal(), args.title, ber_top)
    run_gnuplot(script, args.png)
    print("pareto_plot: wrote " + args.png)


def cmd_front(args):
    rows = read_csv(args.csv)
    for name in (args.x, args.y):
        if rows and name not in rows[0]:
            fail("%s: no column '%s'" % (args.csv, name))
    idx = pareto_front([(finite(r[args.x]), finite(r[args.y])) for r in rows], args.maximize)
    for i in idx:
        print(",".join(str(rows[i][k]) for k in rows[i]))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("train-csv")
    p.add_argument("runs", nargs="+")
    p.add_argument("--out", required=True)
    p.set_defaults(fn=cmd_train_csv)
    p = sub.add_parser("embed-csv")
    p.add_argument("points", nargs="+")
    p.add_argument("--out", required=True)
    p.set_defaults(fn=cmd_embed_csv)
    p = sub.add_parser("plot-train")
    p.add_argument("csv")
    p.add_argument("--png", required=True)
    p.add_argument("--title", default="3DGS training: held-out PSNR against wall time")
    p.set_defaults(fn=cmd_plot_train)
    p = sub.add_parser("plot-embed")
    p.add_argument("csv")
    p.add_argument("--png", required=True)
    p.add_argument("--title", default="WATER-GS embedding: BER and PSNR against wall time")
    p.set_defaults(fn=cmd_plot_embed)
    p = sub.add_parser("front")
    p.add_argument("csv")
    p.add_argument("--x", required=True)
    p.add_argument("--y", required=True)
    p.add_argument("--maximize", action="store_true")
    p.set_defaults(fn=cmd_front)
    args = parser.parse_args()
    args.fn(args)


if __name__ == "__main__":
    main()
