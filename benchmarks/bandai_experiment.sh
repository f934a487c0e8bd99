#!/usr/bin/env bash
# Paper 000's protocol (sec. 6, ../shared/METHODS.md sec. 4) on real motion: Bandai Namco
# walk and run takes (../shared/data/bandai_walk_run, 30 Hz BVH) converted to HumanEva poses
# at 60 Hz, the test takes rendered into 4 noisy 80x60 silhouette views; one manifold per
# activity, trained on one take, dynamics fitted on another, tested on a third.
#
#   bash benchmarks/bandai_experiment.sh [OUT]          (RUNS=5 BUDGET=500 by default)
#
# Writes OUT/walk and OUT/run (results.json, table.md, error_curves.png, overlay GIFs).
set -euo pipefail
DATA=${DATA:-../shared/data/bandai_walk_run}
OUT=${1:-bandai_experiment}
RUNS=${RUNS:-5}
BUDGET=${BUDGET:-500}
if [ ! -d "$DATA" ]; then echo "no Bandai data at $DATA (set DATA=...)" >&2; exit 2; fi
mkdir -p "$OUT"
for take in walk_normal_001 walk_normal_002 walk_normal_003 run_normal_001 run_normal_002 run_normal_003 run_normal_005 \
        walk_normal_004 run_normal_006; do  # the last two: real_motion.py --sequences held-out
    [ -f "$OUT/$take.npz" ] || jaxtrack convert "$DATA/dataset-2_$take.bvh" "$OUT/$take.npz" --fps 60
done
# Test scenes: the first 200 frames of the walk (as 000 does), the first 80 of the run
# (1.3 s; a longer run leaves the 4 m capture area). (Run 004 is skipped: inverse
# kinematics cannot fit its first 20 frames, 28 mm on average, from any start.)
[ -f "$OUT/walk_test.npz" ] || jaxtrack scene "$OUT/walk_normal_003.npz" "$OUT/walk_test.npz" --frames 200 --seed 1
[ -f "$OUT/run_test.npz" ] || jaxtrack scene "$OUT/run_normal_005.npz" "$OUT/run_test.npz" --frames 80 --seed 2
jaxtrack experiment --train "$OUT/walk_normal_001.npz" --validation "$OUT/walk_normal_002.npz" \
    --test "$OUT/walk_test.npz" --runs "$RUNS" --budget "$BUDGET" --out "$OUT/walk"
jaxtrack experiment --train "$OUT/run_normal_001.npz" "$OUT/run_normal_002.npz" --validation "$OUT/run_normal_003.npz" \
    --test "$OUT/run_test.npz" --runs "$RUNS" --budget "$BUDGET" --out "$OUT/run"
