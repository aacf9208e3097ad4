#!/usr/bin/env python3
"""Bookkeeping of a watergs batch (scripts/slurm/watergs_batch.sh): the scene manifest, per-scene status
files, which scenes still have to run, and the final table over every scene.

Subcommands (each error is one line naming the file and the problem, exit status 1):
  manifest   reads a manifest (one scene per line: WORKSPACE [key=value ...]), checks it, fills in the
             driver's defaults and writes the scene table (TSV) atomically
  row        prints one scene's fields of a scene table, NUL-separated, then its fingerprint, then each
             *_args option list as its length and its words (read by run_scene.sh)
  pending    prints the indices of the scenes that still have to run, comma-separated
  status     writes a scene's status.json atomically
  aggregate  writes OUT/summary.{csv,json,md} atomically from every scene's status and eval report

Python standard library only: it runs on a bare Debian's /usr/bin/python3 as well as in a virtualenv.
"""
import argparse
import csv
import datetime
import hashlib
import io
import json
import os
import re
import shlex
import socket
import sys
import tempfile

# Scene table columns, in order; run_scene.sh reads them in this order too.
FIELDS = ["name", "workspace", "ply", "downscale", "train_iterations", "embed_iterations", "message", "decoder",
          "seed", "attacks", "train_args", "embed_args", "eval_args"]
PATH_KEYS = {"workspace", "ply", "decoder"}
ARGS_KEYS = ["train_args", "embed_args", "eval_args"]  # further watergs options, shell-quoted
INT_KEYS = {"downscale": 1, "train_iterations": 1, "embed_iterations": 1, "seed": 0}  # key -> smallest value
DEFAULT_ATTACKS = "identity,gn:0.01,dropout:0.1,crop:0.1"
NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
STATES = ("running", "done", "failed", "interrupted")


class Error(Exception):
    pass


def write_atomically(path, text):
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", dir=folder)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


# ---------------------------------------------------------------------------------------------- manifest

def parse_manifest(path, defaults):
    """Scenes of a manifest as dicts over FIELDS (paths absolute, defaults filled in)."""
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise Error(f"{path}: cannot read the manifest ({e})")
    base = os.path.dirname(os.path.abspath(path))
    scenes, names = [], {}
    for number, line in enumerate(lines, 1):
        where = f"{path}:{number}"
        try:
            words = shlex.split(line, comments=True)
        except ValueError as e:
            raise Error(f"{where}: {e}")
        if not words:
            continue
        scene = dict(defaults)
        scene["workspace"] = words[0]
        if "=" in words[0]:
            raise Error(f"{where}: the line must start with the workspace folder, not '{words[0]}'")
        for word in words[1:]:
            key, sep, value = word.partition("=")
            if not sep:
                raise Error(f"{where}: '{word}' is not key=value (keys: {', '.join(FIELDS[:1] + FIELDS[2:])})")
            if key not in FIELDS or key == "workspace":
                raise Error(f"{where}: unknown key '{key}' (keys: {', '.join(FIELDS[:1] + FIELDS[2:])})")
            scene[key] = value
        for key in PATH_KEYS:
            if scene.get(key):
                scene[key] = os.path.normpath(os.path.join(base, os.path.expanduser(scene[key])))
        scene.setdefault("name", "")
        if not scene["name"]:
            scene["name"] = os.path.basename(scene["workspace"].rstrip("/"))
        check_scene(scene, where)
        if scene["name"] in names:
            raise Error(f"{where}: scene name '{scene['name']}' is also on line {names[scene['name']]} "
                        "(give one a name=...)")
        names[scene["name"]] = number
        scenes.append(scene)
    if not scenes:
        raise Error(f"{path}: no scene in the manifest (one per line: WORKSPACE [key=value ...])")
    return scenes


def check_scene(scene, where):
    for key in FIELDS:
        scene[key] = scene.get(key) or ""
        if any(c in scene[key] for c in "\t\n\r\0"):
            raise Error(f"{where}: {key} contains a tab, newline or NUL")
    if not NAME_RE.match(scene["name"]):
        raise Error(f"{where}: scene name '{scene['name']}' must be letters, digits, '.', '_' or '-'")
    ws = scene["workspace"]
    if not os.path.isdir(ws):
        raise Error(f"{where}: workspace '{ws}' is not a folder")
    for sub in ("images", "sparse/0"):
        if not os.path.isdir(os.path.join(ws, sub)):
            raise Error(f"{where}: workspace '{ws}' has no {sub}/ folder (not a COLMAP workspace)")
    if scene["ply"] and not os.path.isfile(scene["ply"]):
        raise Error(f"{where}: ply '{scene['ply']}' not found")
    if not scene["decoder"]:
        raise Error(f"{where}: no decoder (the driver's --decoder or decoder=...)")
    if not os.path.isfile(scene["decoder"]):
        raise Error(f"{where}: decoder '{scene['decoder']}' not found")
    if not scene["message"]:
        raise Error(f"{where}: no message for scene '{scene['name']}' (the driver's --message or message=...)")
    for key, low in INT_KEYS.items():
        value = scene[key]
        if value and not (value.isdigit() and int(value) >= low):
            raise Error(f"{where}: {key} '{value}' is not a whole number >= {low}")
    for key in ARGS_KEYS:
        try:
            shlex.split(scene[key])
        except ValueError as e:
            raise Error(f"{where}: {key} '{scene[key]}': {e}")
    if not scene["attacks"]:
        scene["attacks"] = DEFAULT_ATTACKS
    if any(c.isspace() for c in scene["attacks"]):
        raise Error(f"{where}: attacks '{scene['attacks']}' contains spaces (comma-separated, as watergs eval)")


def read_table(path):
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except OSError as e:
        raise Error(f"{path}: cannot read the scene table ({e})")
    scenes = []
    for number, line in enumerate(lines, 1):
        if line.startswith("#") or not line:
            continue
        values = line.split("\t")
        if len(values) != len(FIELDS):
            raise Error(f"{path}:{number}: {len(values)} fields, expected {len(FIELDS)} (a damaged scene table)")
        scenes.append(dict(zip(FIELDS, values)))
    return scenes


def fingerprint(scene):
    """Identifies what a scene's outputs were made from: every field but the name."""
    text = "\t".join(scene[k] for k in FIELDS if k != "name")
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def cmd_manifest(args):
    defaults = {}
    for item in args.set:
        key, _, value = item.partition("=")
        if key not in FIELDS:
            raise Error(f"--set {item}: unknown key '{key}'")
        defaults[key] = value
    for key in PATH_KEYS:
        if defaults.get(key):
            defaults[key] = os.path.abspath(defaults[key])
    scenes = parse_manifest(args.manifest, defaults)
    text = "# " + "\t".join(FIELDS) + "\n" + "".join("\t".join(s[k] for k in FIELDS) + "\n" for s in scenes)
    for out in args.output:
        write_atomically(out, text)
    print(len(scenes))


def cmd_row(args):
    scenes = read_table(args.scenes)
    if not args.index.isdigit() or int(args.index) >= len(scenes):
        raise Error(f"{args.scenes}: no scene with index '{args.index}' (the table has {len(scenes)}: 0-"
                    f"{len(scenes) - 1})")
    scene = scenes[int(args.index)]
    items = [scene[k] for k in FIELDS] + [fingerprint(scene)]
    for key in ARGS_KEYS:  # then each option list: its length, its words
        words = shlex.split(scene[key])
        items += [str(len(words))] + words
    sys.stdout.write("\0".join(items) + "\0")


# ---------------------------------------------------------------------------------------------- status

def status_path(out_dir, name):
    return os.path.join(out_dir, "scenes", name, "status.json")


def read_status(path):
    """A scene's status dict, or None when it never ran; a damaged file reads as 'interrupted'."""
    try:
        with open(path) as f:
            status = json.load(f)
        if not isinstance(status, dict) or status.get("state") not in STATES:
            raise ValueError("no valid state")
        return status
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as e:
        return {"state": "interrupted", "error": f"{path}: unreadable status ({e})"}


def cmd_status(args):
    status = {"scene": args.scene, "state": args.state, "step": args.step, "error": args.error,
              "fingerprint": args.fingerprint, "host": socket.gethostname(),
              "time": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")}
    job = os.environ.get("SLURM_ARRAY_JOB_ID") or os.environ.get("SLURM_JOB_ID")
    if job:
        status["slurm_job"] = f"{job}_{os.environ['SLURM_ARRAY_TASK_ID']}" if os.environ.get(
            "SLURM_ARRAY_TASK_ID") else job
    if os.environ.get("JOB_COMPLETION_INDEX"):
        status["kubernetes_index"] = os.environ["JOB_COMPLETION_INDEX"]
    write_atomically(args.file, json.dumps(status, indent=2) + "\n")


def cmd_pending(args):
    scenes = read_table(args.scenes)
    pending = []
    for index, scene in enumerate(scenes):
        name = scene["name"]
        status = read_status(status_path(args.output_path, name))
        state = status["state"] if status else None
        if state == "done":
            if status.get("fingerprint") != fingerprint(scene):
                print(f"skip {name}: done, but with other manifest options than now; delete "
                      f"{os.path.join(args.output_path, 'scenes', name)} to run it again", file=sys.stderr)
            else:
                print(f"skip {name}: done", file=sys.stderr)
            continue
        if state == "failed" and not args.retry_failed:
            print(f"skip {name}: failed at {status.get('step') or '?'}: {status.get('error') or '?'} "
                  "(--retry_failed runs it again)", file=sys.stderr)
            continue
        why = {None: "not run yet", "running": "was running (an earlier task still running exits at once)",
               "interrupted": f"interrupted ({status.get('error') if status else ''}); resumes",
               "failed": "failed before; retried"}[state]
        print(f"run {name}: {why}", file=sys.stderr)
        pending.append(str(index))
    print(",".join(pending))


# ---------------------------------------------------------------------------------------------- aggregate

def read_seconds(path):
    try:
        with open(path) as f:
            return float(f.read().strip())
    except (OSError, ValueError):
        return None


def load_eval(path):
    with open(path) as f:
        report = json.load(f)
    quality = {q["comparison"]: q["mean"] for q in report["quality"]}
    bers = {}
    for row in report["robustness"]:
        if row["kind"] != "3d":
            continue
        key = "raw" if row["model"] == "raw" else row["attack"]
        bers[key] = 100.0 * row["ber"]
    return report, quality, bers


def fmt(value, digits):
    return "" if value is None else f"{value:.{digits}f}"


def cmd_aggregate(args):
    scenes = read_table(args.scenes)
    attacks = []
    for scene in scenes:
        for attack in scene["attacks"].split(","):
            if attack and attack not in attacks:
                attacks.append(attack)
    rows, problems = [], []
    for scene in scenes:
        name = scene["name"]
        scene_dir = os.path.join(args.output_path, "scenes", name)
        status = read_status(status_path(args.output_path, name))
        state = status["state"] if status else "not run"
        row = {"scene": name, "state": state, "bits": None, "ber": {}, "psnr_wm": None, "psnr_raw": None,
               "psnr_wm_vs_raw": None, "gaussians": None,
               "train_s": None if scene["ply"] else read_seconds(os.path.join(scene_dir, "train.seconds")),
               "embed_s": read_seconds(os.path.join(scene_dir, "embed.seconds")),
               "eval_s": read_seconds(os.path.join(scene_dir, "eval.seconds")),
               "step": status.get("step", "") if status and state != "done" else "",
               "error": status.get("error", "") if status and state != "done" else ""}
        if state == "done":
            try:
                report, quality, bers = load_eval(os.path.join(scene_dir, "eval.json"))
                row.update(bits=report["num_bits"], ber=bers, gaussians=report["watermarked_gaussians"],
                           psnr_wm=quality["watermarked vs ground truth"]["psnr"],
                           psnr_raw=quality["raw vs ground truth"]["psnr"],
                           psnr_wm_vs_raw=quality["watermarked vs raw renders"]["psnr"])
            except (OSError, ValueError, KeyError, TypeError) as e:
                row.update(state="failed", step="aggregate",
                           error=f"{os.path.join(scene_dir, 'eval.json')}: unreadable eval report ({e})")
        elif state == "not run":
            row["error"] = "no status: its task never started or was killed before it began (see the Slurm log)"
        elif state == "running":
            row["error"] = "still running, or killed without notice (out of memory, node failure); resubmit"
        if row["state"] != "done":
            problems.append(row)
        rows.append(row)
    times = [sum(t for t in (r["train_s"], r["embed_s"], r["eval_s"]) if t is not None) for r in rows]

    csv_fields = (["scene", "state", "bits"] + [f"ber_{a}" for a in attacks] +
                  ["ber_raw", "psnr_wm", "psnr_raw", "psnr_wm_vs_raw", "gaussians",
                   "train_s", "embed_s", "eval_s", "total_s", "step", "error"])
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(csv_fields)
    for r, total in zip(rows, times):
        writer.writerow([r["scene"], r["state"], r["bits"] or ""] +
                        [fmt(r["ber"].get(a), 4) for a in attacks] +
                        [fmt(r["ber"].get("raw"), 4), fmt(r["psnr_wm"], 3), fmt(r["psnr_raw"], 3),
                         fmt(r["psnr_wm_vs_raw"], 3), r["gaussians"] or "", fmt(r["train_s"], 1),
                         fmt(r["embed_s"], 1), fmt(r["eval_s"], 1), fmt(total or None, 1), r["step"], r["error"]])

    done = [r for r in rows if r["state"] == "done"]
    summary = {"scenes": len(rows), "done": len(done), "problems": len(problems), "attacks": attacks,
               "rows": [dict(r, total_s=t) for r, t in zip(rows, times)],
               "failed": [{"scene": r["scene"], "state": r["state"], "step": r["step"], "error": r["error"]}
                          for r in problems]}

    md = [f"watergs batch: {len(done)} of {len(rows)} scenes done, {len(problems)} not "
          "(BER in % of the message bits on the held-out views; PSNR in dB against the ground truth)", "",
          "| scene | " + " | ".join(f"BER {a}" for a in attacks) +
          " | BER raw | PSNR wm | PSNR raw | train s | embed s | eval s |",
          "|---|" + "---:|" * (len(attacks) + 6)]
    for r in done:
        md.append(f"| {r['scene']} | " + " | ".join(fmt(r["ber"].get(a), 2) for a in attacks) +
                  f" | {fmt(r['ber'].get('raw'), 2)} | {fmt(r['psnr_wm'], 2)} | {fmt(r['psnr_raw'], 2)} | "
                  f"{fmt(r['train_s'], 1) or 'given'} | {fmt(r['embed_s'], 1)} | {fmt(r['eval_s'], 1)} |")
    if problems:
        md += ["", "Not done:"]
        md += [f"- {r['scene']}: {r['state']}" + (f" at {r['step']}" if r["step"] else "") + f": {r['error']}"
               for r in problems]
    md_text = "\n".join(md) + "\n"

    write_atomically(os.path.join(args.output_path, "summary.csv"), buf.getvalue())
    write_atomically(os.path.join(args.output_path, "summary.json"), json.dumps(summary, indent=2) + "\n")
    write_atomically(os.path.join(args.output_path, "summary.md"), md_text)
    sys.stdout.write(md_text)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("manifest")
    p.add_argument("--manifest", required=True)
    p.add_argument("--output", action="append", required=True, help="scene table to write (repeatable)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="default for every scene")
    p = sub.add_parser("row")
    p.add_argument("--scenes", required=True)
    p.add_argument("--index", required=True)
    p = sub.add_parser("pending")
    p.add_argument("--scenes", required=True)
    p.add_argument("--output_path", required=True)
    p.add_argument("--retry_failed", action="store_true")
    p = sub.add_parser("status")
    p.add_argument("--file", required=True)
    p.add_argument("--scene", required=True)
    p.add_argument("--state", required=True, choices=STATES)
    p.add_argument("--step", default="")
    p.add_argument("--error", default="")
    p.add_argument("--fingerprint", default="")
    p = sub.add_parser("aggregate")
    p.add_argument("--scenes", required=True)
    p.add_argument("--output_path", required=True)
    args = parser.parse_args()
    try:
        {"manifest": cmd_manifest, "row": cmd_row, "pending": cmd_pending, "status": cmd_status,
         "aggregate": cmd_aggregate}[args.command](args)
    except Error as e:
        sys.exit(f"error: {e}")
    except OSError as e:
        sys.exit(f"error: {e.filename or ''}: {e.strerror or e}")


if __name__ == "__main__":
    main()
