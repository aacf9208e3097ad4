#!/usr/bin/env bash
# The demo at a quarter of its resolution (120x90), as a test of the watermark itself with the
# shipped decoder: train, embed with nothing but the required options (the defaults are the
# product), attack the file, then read it back as the owner does (extract --raw_path: each view's
# logits minus the raw model's) and blind (the decoder alone): the default embedding optimises both
# readings. Asserts per single
# view, not only in aggregate:
#  - the raw model reads "absent" over all cameras blind, and a second raw model trained alone (another
#    seed: an unmarked model of the same scene, what an honest third party could hold) reads "absent"
#    as the owner's suspect against the first (the control; the raw model against a copy of itself
#    would read "absent" by the tie rule alone);
#  - the watermarked file and its gn / dropout / crop copies read "present" over all cameras;
#  - the watermarked file read blind over all cameras (the decoder alone; the default embedding
#    serves both readers): "present" together, one view at most MAX_BLIND_VIEW_BER of the bits wrong
#    on average, and the raw model at least MIN_RAW_VIEW_BER;
#  - the 6 held-out cameras (unseen in training and embedding) read "present" together, and one
#    held-out view alone reads at most MAX_MEAN_ERRORS of 48 bits wrong on average, at most
#    MAX_P90_ERRORS at the 90th percentile;
#  - the watermarked renders of the held-out views stay at least MIN_PSNR_VS_RAW dB from the raw
#    model's (the embedding is meant to be invisible);
#  - embedding leaves the Gaussian count as it was (density control is off by default).
# The bounds are the figures measured at this size (docs/history.md) with a few bits of slack.
set -euo pipefail
bin="${WATERGS_BIN:?WATERGS_BIN: the watergs CLI}"
root="$(cd "$(dirname "$0")/../.." && pwd)"
scene="$root/datasets_scripts/demo_scene"
decoder="$root/watermark/models/decoder_48_residual_pool2.bin"  # every command's default
message="text:WGS-26"
MAX_MEAN_ERRORS="${MAX_MEAN_ERRORS:-3}"  # of 48, mean over the 6 held-out views as the owner (measured 1.50)
MAX_P90_ERRORS="${MAX_P90_ERRORS:-4}"    # measured 2
# dB, held-out views (measured 35.73 with the residual + pool 2 decoder and --reading both; the first
# default, decoder_48.bin and --reading owner, 38.03: at 120x90 the finer band costs more pixels)
MIN_PSNR_VS_RAW="${MIN_PSNR_VS_RAW:-35}"
# Blind single views over all cameras, the fraction of bits wrong on average: the default embedding
# serves the decoder alone too (measured 0.0625 here; the demo at 240x180 reads 0.022 over its 48
# cameras, results/demo; chance is 0.5), and the raw model reads near chance (measured 0.488).
MAX_BLIND_VIEW_BER="${MAX_BLIND_VIEW_BER:-0.12}"
MIN_RAW_VIEW_BER="${MIN_RAW_VIEW_BER:-0.40}"
# Extra embed options, to see the test fail on a weaker embedding (e.g. --margin 0).
read -r -a extra <<< "${EMBED_EXTRA_ARGS:-}"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
# The thresholds were measured on the CPU; a GPU machine would run auto on cuda.
common=(--workspace_path "$scene" --downscale 4 --device cpu)
fail() { echo "reduced_demo_test: FAIL: $*" >&2; exit 1; }

# The second raw model trains on the other core meanwhile.
train_args=(--iterations 2000 --densify_until_iter 1000 --split train --test_iterations 2000 --num_threads 1)
"$bin" train "${common[@]}" --output_path "$out/train2" "${train_args[@]}" --seed 1 > "$out/train2.log" 2>&1 &
train2=$!
"$bin" train "${common[@]}" --output_path "$out/train" "${train_args[@]}" > "$out/train.log"
raw="$out/train/point_cloud.ply"
wait "$train2" || { cat "$out/train2.log"; fail "training the second raw model"; }
raw2="$out/train2/point_cloud.ply"
cmp -s "$raw" "$raw2" && fail "the raw model with --seed 1 is the seed-0 file"
"$bin" embed --input_path "$raw" "${common[@]}" --decoder "$decoder" --message "$message" \
  --output_path "$out/wm.ply" --split train --num_threads 1 "${extra[@]}" > "$out/embed.log" 2>&1 || { cat "$out/embed.log"; fail "embed"; }
count() { "$bin" ply_info --input_path "$1" | awk '/^Gaussians:/ {print $2}'; }
[ "$(count "$raw")" = "$(count "$out/wm.ply")" ] || fail "embedding changed the Gaussian count"

extract() {  # NAME PLY [extract options...]: writes $out/NAME.json, prints the owner's verdict
  local name=$1 ply=$2; shift 2
  "$bin" extract --input_path "$ply" "${common[@]}" --decoder "$decoder" --message "$message" \
    --num_threads 1 --json "$out/$name.json" "$@" > "$out/$name.txt"
  python3 -c 'import json,sys; j=json.load(open(sys.argv[1])); print(j.get("owner", j)["verdict"])' "$out/$name.json"
}
[ "$(extract raw "$raw")" = "watermark absent" ] || fail "raw model not 'absent' blind: $(cat "$out/raw.txt")"
# As the owner: an unmarked model trained alone, read against the owner's raw model.
[ "$(extract raw_owner "$raw2" --raw_path "$raw")" = "watermark absent" ] ||
  fail "a raw model trained alone not 'absent' as the owner: $(cat "$out/raw_owner.txt")"
python3 - "$out/raw_owner.json" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))["owner"]
print(f"raw model trained alone (--seed 1), the owner's suspect: BER {j['ber']:.2%}, {j['verdict']}, "
      f"one view mean {j['view_ber']['mean']:.2%}")
PY
for attack in identity gn:0.01 dropout:0.1 crop:0.1; do
  ply="$out/wm.ply"
  if [ "$attack" != identity ]; then
    ply="$out/wm_${attack%%:*}.ply"
    "$bin" attack --input_path "$out/wm.ply" --attack "$attack" --output_path "$ply" > /dev/null
  fi
  v=$(extract "wm_${attack%%:*}" "$ply" --raw_path "$raw")
  [ "$v" = "watermark present" ] || fail "$attack: '$v' over all cameras"
done
python3 - "$out/wm_identity.json" "$MAX_BLIND_VIEW_BER" "$out/raw.json" "$MIN_RAW_VIEW_BER" <<'PY'
import json, sys
wm, raw = json.load(open(sys.argv[1])), json.load(open(sys.argv[3]))
for name, j in (("watermarked", wm), ("raw", raw)):
    print(f"{name} read blind over {j['num_views']} cameras: BER {j['ber']:.2%}, {j['verdict']}, "
          f"one view mean {j['view_ber']['mean']:.2%}")
assert wm["verdict"] == "watermark present", f"watermarked, blind over all cameras: {wm['verdict']}"
assert wm["view_ber"]["mean"] <= float(sys.argv[2]), \
    f"watermarked, blind: one view mean {wm['view_ber']['mean']:.4f} > {sys.argv[2]}"
assert raw["view_ber"]["mean"] >= float(sys.argv[4]), \
    f"raw, blind: one view mean {raw['view_ber']['mean']:.4f} < {sys.argv[4]}"
PY
v=$(extract held "$out/wm.ply" --split test --raw_path "$raw")
[ "$v" = "watermark present" ] || fail "held-out views together: '$v'"
"$bin" eval --raw_path "$raw" --input_path "$out/wm.ply" "${common[@]}" --decoder "$decoder" \
  --message "$message" --attacks '' --image_attacks '' --lpips_weights '' --num_threads 1 \
  --output_path "$out/eval" > /dev/null
python3 - "$out/held.json" "$MAX_MEAN_ERRORS" "$MAX_P90_ERRORS" "$out/eval.json" "$MIN_PSNR_VS_RAW" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))["owner"]
quality = {q["comparison"]: q["mean"]["psnr"] for q in json.load(open(sys.argv[4]))["quality"]}
vs_raw = quality["watermarked vs raw renders"]
print(f"held-out PSNR: {quality['watermarked vs ground truth']:.2f} dB vs the photos "
      f"(raw {quality['raw vs ground truth']:.2f}), {vs_raw:.2f} dB vs the raw renders")
assert vs_raw >= float(sys.argv[5]), f"{vs_raw:.2f} dB from the raw renders < {sys.argv[5]}"
errors = sorted(v["bit_errors"] for v in j["views"])
mean = sum(errors) / len(errors)
# p90 by its definition (the smallest count at least 90% of views do not exceed), then the tool's
# own mean and p90 (extract's JSON) against these.
p90 = min(e for e in errors if 10 * sum(x <= e for x in errors) >= 9 * len(errors))
print(f"held-out single views as the owner: bit errors {errors}, mean {mean:.2f}, p90 {p90} of {j['num_bits']}")
spread = j["view_ber"]
assert abs(spread["mean"] - mean / j["num_bits"]) < 1e-9, f"extract's mean {spread['mean']} != {mean / j['num_bits']}"
assert abs(spread["p90"] - p90 / j["num_bits"]) < 1e-9, f"extract's p90 {spread['p90']} != {p90 / j['num_bits']}"
assert len(errors) == 6, f"{len(errors)} held-out views, expected 6"
assert mean <= float(sys.argv[2]), f"mean {mean:.2f} bit errors per held-out view > {sys.argv[2]}"
assert p90 <= int(sys.argv[3]), f"p90 {p90} bit errors per held-out view > {sys.argv[3]}"
PY
echo "reduced_demo_test: passed"
