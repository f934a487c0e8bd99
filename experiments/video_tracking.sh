#!/usr/bin/env bash
# The video path end to end (docs/video.md): CMU subject 35's walk filmed in colour by
# `jaxtrack scene --rgb --video` (the solid body, not the tracker's capsules, over a real
# photograph, with cast shadows, a lighting change and sensor noise), then tracked by MRPF
# (a) from the videos, the silhouettes by background subtraction, started automatically, no
#     ground truth read;
# (b) the same with the 2-D keypoints (5 px noise, 10 % dropped) summed in;
# (c) the same with 001's edge and foreground terms summed in (160x120 only: 4 frames/s);
# (r) the reference: the renderer's true silhouettes, started from the truth.
# Every run tracks with BODY (default: the default body; "auto" calibrates it from the first
# frames where the person is tall enough, and falls back to the default where that fails,
# which makes runs differ in their body as well as their cue), and BODY_PRIOR what centres a
# calibration's prior (--body-prior; default: default; give each its own OUT).
# Env: CMU (converted takes, benchmarks/cmu_experiment.sh), OUT, FRAMES, SIZES, VIEWS, SEEDS, BODY, BODY_PRIOR.
set -euo pipefail
CMU=${CMU:-/tmp/cmu}
OUT=${OUT:-/tmp/video_study}
FRAMES=${FRAMES:-100}
SIZES=${SIZES:-"160x120 320x240"}
VIEWS=${VIEWS:-"4 3"}
SEEDS=${SEEDS:-"0"}
BODY=${BODY:-default}
BODY_PRIOR=${BODY_PRIOR:-default}
mkdir -p "$OUT"
[ -f "$OUT/walk.eqx" ] || jaxtrack fit "$CMU/35_01.npz" "$CMU/35_02.npz" --model bc-gplvm --latent-dim 2 --out "$OUT/walk.eqx"
for size in $SIZES; do
  for views in $VIEWS; do
    film="$OUT/film_${size}_${views}"
    w=${size%x*}; h=${size#*x}
    [ -f "$film/truth.npz" ] || jaxtrack scene "$CMU/35_29.npz" --rgb --video "$film" --frames "$FRAMES" --width "$w" --height "$h" --views "$views"
    cams=$(python -c "import json;print(' '.join('$film/'+c['name']+'.mp4' for c in json.load(open('$film/calibration.json'))['cameras']))")
    bgs=$(python -c "import json;print(' '.join('$film/background/'+c['name']+'.mp4' for c in json.load(open('$film/calibration.json'))['cameras']))")
    common="--model $OUT/walk.eqx --validation $CMU/35_03.npz --method mrpf --chunk-frames 0 --body $BODY --body-prior $BODY_PRIOR"
    for seed in $SEEDS; do
      run="$OUT/${size}_${views}_s${seed}_$BODY"
      [ -f "${run}_reference.npz" ] || jaxtrack track "$film/truth.npz" $common --seed "$seed" --out "${run}_reference.npz"
      [ -f "${run}_video.npz" ] || jaxtrack track --video $cams --background $bgs --calibration "$film/calibration.json" $common \
          --seed "$seed" --out "${run}_video.npz" --overlay "${run}_video.mp4"
      [ -f "${run}_keypoints.npz" ] || jaxtrack track --video $cams --background $bgs --calibration "$film/calibration.json" $common \
          --keypoints "$film/keypoints.npz" --likelihood silhouette+keypoints --seed "$seed" --out "${run}_keypoints.npz"
      if [ "$size" = "160x120" ]; then
        [ -f "${run}_edges.npz" ] || jaxtrack track --video $cams --background $bgs --calibration "$film/calibration.json" $common \
            --likelihood silhouette+edge+foreground --seed "$seed" --out "${run}_edges.npz"
      fi
    done
  done
done
python - "$OUT" <<'PY'
import glob, os, sys
import numpy as np
from jaxtrack.io import load_sequence
out = sys.argv[1]
print("| images | views | seed | body | run | mean error (mm) | frame 0 (mm) |")
print("|---|---|---|---|---|---|---|")
means = {}
for path in sorted(glob.glob(os.path.join(out, "*x*_*_s*_*_*.npz"))):
    size, views, seed, body, run = os.path.basename(path)[:-4].split("_", 4)
    truth = load_sequence(os.path.join(out, f"film_{size}_{views}", "truth.npz")).joints3d
    est = load_sequence(path).joints3d
    err = 1000 * np.linalg.norm(est - truth[: len(est)], axis=-1).mean(axis=-1)
    print(f"| {size} | {views} | {seed[1:]} | {body} | {run} | {err.mean():.1f} | {err[0]:.1f} |")
    means.setdefault((size, views, body), {}).setdefault(run, []).append((err.mean(), err[0]))
print()
print("| images | views | body | run | seeds | mean error (mm) | frame 0 (mm) | over the reference |")
print("|---|---|---|---|---|---|---|---|")
for (size, views, body), runs in sorted(means.items()):
    reference = np.mean([e for e, _ in runs.get("reference", [(np.nan, np.nan)])])
    for run, rows in sorted(runs.items()):
        mean, first = np.mean(rows, axis=0)
        print(f"| {size} | {views} | {body} | {run} | {len(rows)} | {mean:.1f} | {first:.1f} | {mean / reference:.2f} |")
PY
