#!/usr/bin/env bash
# CTest: scripts/slurm/watergs_batch.sh on a real Slurm (Debian's slurm-wlm and munge, started here in a
# temporary folder by scripts/slurm/local_slurm.sh, stopped on every exit). A 3-scene array on the demo
# scene at 1/8 resolution, one scene broken (a truncated images.bin):
#   1. the two good scenes' outputs and aggregate rows (equal to their eval reports, with their own
#      manifest options), the broken one failed at train with watergs's one-line error, reported by the
#      aggregate job;
#   2. the same submission again runs nothing: no job, no scene file touched;
#   3. a scene interrupted during its evaluation resumes with only that step, and one whose cached
#      steps were made with other options is refused;
#   4. datasets_scripts/reproduce_tables.sh --slurm submits through the same code (2 scenes, tiny
#      settings): its tables cover both scenes, and the same command again submits nothing;
#   5. a real interruption: an embedding signalled while it runs (scancel --signal=TERM --full) is
#      recorded as interrupted, and the resubmission resumes it from its checkpoint ("resumed at
#      iteration") to a watermarked PLY byte-identical to the uninterrupted run of step 1.
# Exit 77 (CTest skip) only when the Slurm daemons cannot start here, with the reason; with
# WATERGS_REQUIRE_SLURM=1 that is a failure too (CTest sets it, so the README's test command and CI
# judge alike).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${WATERGS_BIN:-$repo/build/plugin/watergs}"
python="${WATERGS_PYTHON:-python3}"
demo="$repo/datasets_scripts/demo_scene"
begin=$SECONDS

fail() {
  echo "FAIL: $*" >&2
  exit 1
}
[ -x "$bin" ] || fail "watergs binary '$bin' not built"

# /tmp rather than a long TMPDIR: munged's socket path must stay under 108 bytes.
tmp="$(mktemp -d /tmp/watergs_slurm_test.XXXXXX)"
chmod 755 "$tmp"  # munged's socket lies below it
cleanup() {
  local rc=$?
  bash "$repo/scripts/slurm/local_slurm.sh" stop "$tmp/cluster" >/dev/null 2>&1 || true
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 77 ]; then
    for f in "$tmp"/out/submissions/*/*.out "$tmp"/out/scenes/*/*.log; do
      [ -f "$f" ] && { echo "--- $f:"; tail -n 20 "$f"; }
    done
  fi
  if [ -n "${WATERGS_KEEP_TEST_DIR:-}" ]; then echo "kept $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
trap 'exit 130' INT TERM HUP

rc=0
env_line="$(timeout 90 bash "$repo/scripts/slurm/local_slurm.sh" start "$tmp/cluster")" || rc=$?
if [ "$rc" -eq 3 ] || [ "$rc" -eq 124 ]; then
  [ "$rc" -eq 124 ] && echo "local_slurm.sh start: no idle node within 90 s"
  if [ "${WATERGS_REQUIRE_SLURM:-0}" = 1 ]; then fail "Slurm daemons cannot start (above)"; fi
  echo "SKIP: the Slurm daemons cannot start here (reason above)"
  exit 77
fi
[ "$rc" -eq 0 ] || fail "local_slurm.sh start exited with $rc"
export "${env_line#export }"
echo "Slurm up in $((SECONDS - begin)) s ($SLURM_CONF):"
sinfo

# The broken scene: the demo's images and cameras, its images.bin cut after 300 bytes.
mkdir -p "$tmp/broken/sparse/0"
ln -s "$demo/images" "$tmp/broken/images"
ln -s "$demo/sparse/0/cameras.bin" "$demo/sparse/0/points3D.bin" "$tmp/broken/sparse/0/"
head -c 300 "$demo/sparse/0/images.bin" >"$tmp/broken/sparse/0/images.bin"
cat >"$tmp/manifest.txt" <<EOF
# name, then per-scene options; the driver's options are the defaults
$demo name=alpha
$tmp/broken name=broken
$demo name=beta seed=1 message="text:OWN 02" embed_iterations=200
EOF

out="$tmp/out"
submit=(bash "$repo/scripts/slurm/watergs_batch.sh" --manifest "$tmp/manifest.txt" --output_path "$out"
  --bin "$bin" --message text:WGS-26 --downscale 8 --train_iterations 300 --embed_iterations 300
  --embed_args "--free_view_fraction 0.5 --densify off"
  --cpus_per_task 1 --mem 2G --time 00:10:00 --aggregate_time 00:05:00 --wait)
export SLURM_WAIT_POLL=1

echo "== 1. submission"
t=$SECONDS
rc=0
timeout 600 "${submit[@]}" >"$tmp/run1.txt" 2>&1 || rc=$?
cat "$tmp/run1.txt"
[ "$rc" -eq 1 ] || fail "first submission: exit $rc, expected 1 (a scene is not done)"
grep -q "3 scenes in .*, 3 to run (indices 0,1,2)" "$tmp/run1.txt" || fail "first submission did not submit all 3 scenes"
echo "first submission: $((SECONDS - t)) s"
[ "$(ls -d "$out"/submissions/*/ | wc -l)" -eq 1 ] || fail "expected one submission folder"
ls "$out"/submissions/*/slurm-*_0.out "$out"/submissions/*/slurm-*_1.out "$out"/submissions/*/slurm-*_2.out \
  "$out"/submissions/*/aggregate-*.out >/dev/null || fail "Slurm logs of the 3 tasks and the aggregate job missing"

"$python" - "$out" "$tmp/broken/sparse/0/images.bin" <<'EOF'
import csv, json, os, sys
out, broken_file = sys.argv[1], sys.argv[2]
def fail(msg):
    sys.exit("FAIL: " + msg)
rows = {r["scene"]: r for r in csv.DictReader(open(os.path.join(out, "summary.csv")))}
summary = json.load(open(os.path.join(out, "summary.json")))
if sorted(rows) != ["alpha", "beta", "broken"]:
    fail(f"summary.csv scenes {sorted(rows)}")
bits = {}
for name in ("alpha", "beta"):
    d = os.path.join(out, "scenes", name)
    status = json.load(open(os.path.join(d, "status.json")))
    if status["state"] != "done" or not status.get("slurm_job"):
        fail(f"{name}: status {status}")
    for f in ("train/point_cloud.ply", "watermarked.ply", "eval.json", "eval.md", "train.seconds",
              "embed.seconds", "eval.seconds"):
        if not os.path.getsize(os.path.join(d, f)):
            fail(f"{name}: {f} empty")
    report = json.load(open(os.path.join(d, "eval.json")))
    bits[name] = report["message_bits"]
    row = rows[name]
    if row["state"] != "done" or row["error"]:
        fail(f"{name}: row {row}")
    for r in report["robustness"]:
        if r["kind"] != "3d":
            continue
        key = "ber_raw" if r["model"] == "raw" else "ber_" + r["attack"]
        if abs(float(row[key]) - 100 * r["ber"]) > 1e-3:
            fail(f"{name}: {key} {row[key]} but eval.json says {100 * r['ber']}")
    if not float(row["ber_identity"]) < float(row["ber_raw"]):
        fail(f"{name}: the watermarked model reads no better than the raw one ({row['ber_identity']}% vs "
             f"{row['ber_raw']}%): embedding and evaluation disagree on the message")
    wm = [q for q in report["quality"] if q["comparison"] == "watermarked vs ground truth"][0]
    if abs(float(row["psnr_wm"]) - wm["mean"]["psnr"]) > 1e-2:
        fail(f"{name}: psnr_wm {row['psnr_wm']} vs {wm['mean']['psnr']}")
    for key in ("train_s", "embed_s", "eval_s"):
        if not float(row[key]) > 0:
            fail(f"{name}: {key} '{row[key]}'")
    print(f"{name}: done, BER identity {row['ber_identity']}%, PSNR {row['psnr_wm']} dB, job {status['slurm_job']}")
if bits["alpha"] == bits["beta"]:
    fail("beta's message= did not reach its embedding (same bits as alpha)")
if len(bits["alpha"]) != 48:
    fail(f"alpha's message has {len(bits['alpha'])} bits")
status = json.load(open(os.path.join(out, "scenes", "broken", "status.json")))
row = rows["broken"]
if status["state"] != "failed" or status["step"] != "train":
    fail(f"broken: status {status}")
if not (status["error"].startswith("error: " + broken_file) and "truncated" in status["error"]):
    fail(f"broken: error '{status['error']}' does not name {broken_file} and the problem")
if (row["state"], row["step"], row["error"]) != ("failed", "train", status["error"]):
    fail(f"broken: row {row}")
if summary["done"] != 2 or [f["scene"] for f in summary["failed"]] != ["broken"]:
    fail(f"summary.json: {summary['done']} done, failed {summary['failed']}")
md = open(os.path.join(out, "summary.md")).read()
if "- broken: failed at train: " + status["error"] not in md:
    fail("summary.md does not list the broken scene with its error")
print("broken:", status["error"])
EOF

echo "== 2. the same submission again"
snapshot() { (cd "$out/scenes" && find . -type f ! -name .lock -printf '%p %s %T@\n' | sort); }
snapshot >"$tmp/before.txt"
rc=0
timeout 120 "${submit[@]}" >"$tmp/run2.txt" 2>&1 || rc=$?
cat "$tmp/run2.txt"
[ "$rc" -eq 1 ] || fail "second submission: exit $rc, expected 1 (broken still not done)"
grep -q "3 scenes in .*, 0 to run" "$tmp/run2.txt" || fail "second submission wanted to run scenes"
grep -q "nothing to submit" "$tmp/run2.txt" || fail "second submission submitted jobs"
[ -z "$(find "$out"/submissions -name '*.sbatch' -newer "$tmp/run1.txt")" ] || fail "second submission wrote job scripts"
[ -z "$(squeue -h)" ] || fail "jobs in the queue after the second submission: $(squeue -h)"
snapshot >"$tmp/after.txt"
diff "$tmp/before.txt" "$tmp/after.txt" || fail "the second submission changed scene files"
grep -q "broken: failed at train" "$out/summary.md" || fail "summary lost the broken scene"

echo "== 3. alpha interrupted during its evaluation resumes with that step only"
"$python" "$repo/scripts/slurm/batch_tool.py" status --file "$out/scenes/alpha/status.json" --scene alpha \
  --state interrupted --step eval --error "terminated by SIGTERM (test)" \
  --fingerprint "$(grep -o '"fingerprint": "[0-9a-f]*"' "$out/scenes/alpha/status.json" | cut -d'"' -f4)"
rm "$out/scenes/alpha/eval.seconds" "$out/scenes/alpha/eval.json"
grep -v '^./alpha/eval\|^./alpha/status.json' "$tmp/after.txt" >"$tmp/kept.txt"
rc=0
timeout 300 "${submit[@]}" >"$tmp/run3.txt" 2>&1 || rc=$?
cat "$tmp/run3.txt"
[ "$rc" -eq 1 ] || fail "third submission: exit $rc, expected 1"
grep -q "3 scenes in .*, 1 to run (indices 0)" "$tmp/run3.txt" || fail "third submission should run alpha alone"
# The folder this submission printed ("logs in DIR"): two submissions in one second sort by their
# pid, not by their order ("-10035" before "-9839").
last="$(grep -o 'logs in [^ ]*' "$tmp/run3.txt" | tail -n 1 | cut -d' ' -f3)/"
grep -q "cached: train alpha" "$last"slurm-*_0.out || fail "alpha's training was not reused"
grep -q "cached: embed alpha" "$last"slurm-*_0.out || fail "alpha's embedding was not reused"
snapshot | grep -v '^./alpha/eval\|^./alpha/status.json' | diff "$tmp/kept.txt" - ||
  fail "resuming alpha touched files other than its evaluation"
grep -q '"state": "done"' "$out/scenes/alpha/status.json" || fail "alpha not done after resuming"
grep -q "^alpha,done," "$out/summary.csv" || fail "summary.csv: alpha not done after resuming"

echo "== aggregate table"
cat "$out/summary.md"

echo "== 3b. a scene whose cached steps were made with other options is refused, not finished from them"
"$python" "$repo/scripts/slurm/batch_tool.py" status --file "$out/scenes/alpha/status.json" --scene alpha \
  --state interrupted --step embed --error "terminated by SIGTERM (test)" --fingerprint 0123abcd
rc=0
timeout 300 "${submit[@]}" >"$tmp/run3b.txt" 2>&1 || rc=$?
cat "$tmp/run3b.txt"
[ "$rc" -eq 1 ] || fail "submission with stale alpha: exit $rc, expected 1"
grep -q '"state": "failed"' "$out/scenes/alpha/status.json" || fail "alpha with stale steps was not refused"
grep -q 'other manifest options' "$out/scenes/alpha/status.json" || fail "alpha's refusal does not say why"
grep -q '"fingerprint": "0123abcd"' "$out/scenes/alpha/status.json" ||
  fail "the refusal replaced the fingerprint alpha's steps were made with"

echo "== 4. reproduce_tables.sh --slurm (2 scenes: the demo under two names)"
mkdir -p "$tmp/scenes"
ln -s "$demo" "$tmp/scenes/one"
ln -s "$demo" "$tmp/scenes/two"
reproduce=(bash "$repo/datasets_scripts/reproduce_tables.sh" --output_path "$tmp/reproduce" --bin "$bin"
  --train_iterations 100 --embed_iterations 20 --seeds 0 --downscale 8 --lpips_weights ''
  "$tmp/scenes/one" "$tmp/scenes/two" --slurm --wait --cpus_per_task 1 --mem 2G --time 00:10:00)
t=$SECONDS
timeout 400 "${reproduce[@]}" >"$tmp/reproduce1.txt" 2>&1 || { cat "$tmp/reproduce1.txt"; fail "reproduce_tables.sh --slurm failed"; }
cat "$tmp/reproduce1.txt"
echo "reproduce_tables.sh --slurm: $((SECONDS - t)) s"
grep -q "submitted array job .* (scenes 0,1 of 2)" "$tmp/reproduce1.txt" || fail "reproduce_tables.sh did not submit both scenes"
for k in 0 1; do
  grep -q "scene $k done" "$tmp"/reproduce/submissions/*/slurm-*_"$k".out || fail "reproduce array task $k did not finish"
done
for scene in one two; do
  [ "$(grep -c "^custom,$scene,ALL,on,48,0," "$tmp/reproduce/results.csv")" -eq 1 ] ||
    fail "results.csv lacks scene $scene's robustness run"
  [ "$(grep -c "^custom,$scene," "$tmp/reproduce/results.csv")" -eq 5 ] || fail "results.csv: not 5 runs of scene $scene"
done
rc=0
timeout 120 "${reproduce[@]}" >"$tmp/reproduce2.txt" 2>&1 || rc=$?
[ "$rc" -eq 0 ] || { cat "$tmp/reproduce2.txt"; fail "reproduce_tables.sh --slurm again: exit $rc"; }
grep -q "nothing to submit" "$tmp/reproduce2.txt" || fail "reproduce_tables.sh --slurm again submitted jobs"
[ "$(ls -d "$tmp"/reproduce/submissions/*/ | wc -l)" -eq 1 ] || fail "reproduce_tables.sh --slurm again made a submission"
echo "== 5. an embedding signalled while it runs resumes from its checkpoint"
# gamma is alpha (same workspace, options, seed and thread count) in another output folder, with
# checkpoints every 10 iterations (the signal comes at the first, leaving 290 iterations to interrupt);
# alpha's files from step 1 are the uninterrupted run.
echo "$demo name=gamma" >"$tmp/manifest_resume.txt"
out_resume="$tmp/out_resume"
resume_submit=(bash "$repo/scripts/slurm/watergs_batch.sh" --manifest "$tmp/manifest_resume.txt"
  --output_path "$out_resume" --bin "$bin" --message text:WGS-26 --downscale 8 --train_iterations 300
  --embed_iterations 300 --embed_args "--free_view_fraction 0.5 --densify off" --checkpoint_every 10
  --cpus_per_task 1 --mem 2G --time 00:10:00 --aggregate_time 00:05:00 --wait)
gamma="$out_resume/scenes/gamma"
rm -f "$tmp/resume1.rc"
(
  rc=0
  timeout 600 "${resume_submit[@]}" >"$tmp/resume1.txt" 2>&1 || rc=$?
  echo "$rc" >"$tmp/resume1.rc"
) &
submitter=$!
# Signal once the embedding has written its first checkpoint (not after a fixed time).
for _ in $(seq 1 12000); do
  { [ -f "$gamma/watermarked.ply.ckpt" ] || [ -f "$tmp/resume1.rc" ]; } && break
  sleep 0.05
done
[ -f "$gamma/watermarked.ply.ckpt" ] || { cat "$tmp/resume1.txt"; fail "gamma's embedding wrote no checkpoint"; }
job="$(squeue -h -n watergs-batch -o %A | head -n 1)"
[ -n "$job" ] || fail "gamma's array job is not in the queue"
scancel --signal=TERM --full "$job"
wait "$submitter" || true
cat "$tmp/resume1.txt"
[ "$(cat "$tmp/resume1.rc")" = 1 ] || fail "submission with a signalled embedding: exit $(cat "$tmp/resume1.rc"), expected 1"
[ ! -f "$gamma/embed.seconds" ] || fail "gamma's embedding finished before the signal reached it (no interruption tested)"
grep -q '"state": "interrupted"' "$gamma/status.json" || fail "gamma not interrupted: $(cat "$gamma/status.json")"
grep -q '"step": "embed"' "$gamma/status.json" || fail "gamma not interrupted at embed: $(cat "$gamma/status.json")"
[ -f "$gamma/watermarked.ply.ckpt" ] || fail "the interrupted embedding's checkpoint is gone"
[ ! -e "$gamma/watermarked.ply" ] || fail "an interrupted embedding left a watermarked.ply"
rc=0
timeout 600 "${resume_submit[@]}" >"$tmp/resume2.txt" 2>&1 || rc=$?
cat "$tmp/resume2.txt"
[ "$rc" -eq 0 ] || fail "resubmission after the signal: exit $rc, expected 0"
last="$(grep -o 'logs in [^ ]*' "$tmp/resume2.txt" | tail -n 1 | cut -d' ' -f3)/"
grep -q "cached: train gamma" "$last"slurm-*_0.out || fail "gamma's training was not reused"
grep -E "resumed at iteration [1-9][0-9]*" "$gamma/embed.log" || fail "gamma's embedding did not resume from its checkpoint"
grep -q '"state": "done"' "$gamma/status.json" || fail "gamma not done after resuming"
cmp "$out/scenes/alpha/train/point_cloud.ply" "$gamma/train/point_cloud.ply" ||
  fail "gamma's training differs from alpha's (the runs are not comparable)"
cmp "$out/scenes/alpha/watermarked.ply" "$gamma/watermarked.ply" ||
  fail "the resumed embedding differs from the uninterrupted run"
echo "gamma: signalled during embed, resumed ($(grep -o 'resumed at iteration [0-9]*' "$gamma/embed.log")), same PLY as alpha"

echo "PASS in $((SECONDS - begin)) s"
