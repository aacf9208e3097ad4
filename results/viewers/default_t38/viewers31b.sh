#!/usr/bin/env bash
# Session 31: viewers at 12 free viewpoints (demo) and on fern (held-out + 12 free), default and JPEG layer;
# then the screen recording of the default's demo file. Waits for chain31 (fern/horns runs).
cd /work/main
while ! grep -q "chain done" /work/runs/chain31_horns.log 2>/dev/null; do sleep 30; done
B=/tmp/wgsS31/watergs M=results/viewers/reference_conventions/measure.sh O=/work/runs/viewers31
DRAW=/work/runs/demo31/train/point_cloud.ply
run() { WATERGS_BIN=$B PATH=/usr/bin:$PATH nice bash "$@"; }
FREE_VIEWS=12 run $M $DRAW /work/runs/demo31/wm.ply $O/default_free > $O/default_free.log 2>&1
FREE_VIEWS=12 run $M $DRAW $O/jpeg_layer/wm.ply $O/jpeg_layer_free > $O/jpeg_layer_free.log 2>&1
FRAW=/work/runs/fern_ds2/raw/point_cloud.ply F=/work/runs/fern_ds2/probe/runs
for r in t38 t38j; do
  SCENE=/work/llff/fern_ws run $M $FRAW $F/both_seed0_$r/wm.ply $O/fern_$r > $O/fern_$r.log 2>&1
  SCENE=/work/llff/fern_ws FREE_VIEWS=12 run $M $FRAW $F/both_seed0_$r/wm.ply $O/fern_${r}_free > $O/fern_${r}_free.log 2>&1
done
run results/viewers/recording/measure.sh $DRAW /work/runs/demo31/wm.ply $O/recording > $O/recording.log 2>&1
echo "all done" > $O/b_done
