#!/usr/bin/env bash
cd /work/main
for r in t38 t38j; do
  SETTINGS=auto FREE_VIEWS=12 SCENE=/work/llff/fern_ws WATERGS_BIN=/tmp/wgsS31/watergs PATH=/usr/bin:$PATH nice bash results/viewers/reference_conventions/measure.sh \
    /work/runs/fern_ds2/raw/point_cloud.ply /work/runs/fern_ds2/probe/runs/both_seed0_$r/wm.ply /work/runs/viewers31/fern_${r}_free > /work/runs/viewers31/fern_${r}_free.log 2>&1
done
echo done > /work/runs/viewers31/d_done
