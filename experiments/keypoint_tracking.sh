#!/usr/bin/env bash
# Do 2-D keypoints help the trackers, and do they track alone? CMU subject 35's held-out walk
# (35_29, first FRAMES frames at 60 Hz; converted as benchmarks/cmu_experiment.sh does) rendered
# into noisy silhouettes at 160x120 and 320x240 in 4 and in 3 views, with synthetic detections (the true
# joints projected, N(0, 5 px) noise, 10 % of joints missing: `jaxtrack scene --keypoints`);
# each tracker trained on 35_01 and 35_02, dynamics on 35_03, tracked with the silhouettes
# alone, the keypoints alone, and both. A study for docs/keypoints.md.
#
#   bash experiments/keypoint_tracking.sh [OUT]     (CMU=folder of the converted trials, default cmu_experiment)
set -euo pipefail
CMU=${CMU:-cmu_experiment}
OUT=${1:-keypoint_tracking}
RUNS=${RUNS:-3}
BUDGET=${BUDGET:-500}
FRAMES=${FRAMES:-100}
METHODS=${METHODS:-sir apf mrpf latentpf}
SIZES=${SIZES:-160x120 320x240}
VIEWS=${VIEWS:-4 3}
LIKELIHOODS=${LIKELIHOODS:-silhouette keypoints silhouette+keypoints}  # also: edge+foreground silhouette+edge+foreground
for f in 35_01 35_02 35_03 35_29; do
    [ -f "$CMU/$f.npz" ] || { echo "no $CMU/$f.npz: run benchmarks/cmu_experiment.sh first (or set CMU=...)" >&2; exit 2; }
done
mkdir -p "$OUT"
for size in $SIZES; do
    for views in $VIEWS; do
        scene="$OUT/walk_${size}_${views}views.npz"
        [ -f "$scene" ] || jaxtrack scene "$CMU/35_29.npz" "$scene" --frames "$FRAMES" --width "${size%x*}" --height "${size#*x}" \
            --views "$views" --seed 1 --keypoints --keypoint-noise 5 --keypoint-dropped 0.1
        for likelihood in $LIKELIHOODS; do
            out="$OUT/${size}_${views}views_${likelihood}"
            [ -f "$out/table.md" ] || jaxtrack experiment --train "$CMU/35_01.npz" "$CMU/35_02.npz" --validation "$CMU/35_03.npz" \
                --test "$scene" --methods $METHODS --runs "$RUNS" --budget "$BUDGET" --likelihood "$likelihood" --out "$out"
        done
    done
done
for f in "$OUT"/*views_*/table.md; do echo "== $f"; cat "$f"; done
