#!/usr/bin/env bash
cd /work/main
while pgrep -f "measure.sh /work/runs/fern_ds2" > /dev/null; do sleep 15; done
SETTINGS=auto SCENE=/work/llff/fern_ws WATERGS_BIN=/tmp/wgsS31/watergs PATH=/usr/bin:$PATH nice bash results/viewers/reference_conventions/measure.sh \
  /work/runs/fern_ds2/raw/point_cloud.ply /work/runs/fern_ds2/probe/runs/both_seed0_t38j/wm.ply /work/runs/viewers31/fern_t38j > /work/runs/viewers31/fern_t38j.log 2>&1
echo done > /work/runs/viewers31/c_done
