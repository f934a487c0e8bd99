"""Background subtraction against the true silhouettes of a filmed scene (docs/image.md).

    jaxtrack scene MOTION.npz --rgb --video DIR [--width 320 --height 240 --views 3 ...]
    python experiments/background_iou.py DIR [--json PATH]

Prints, per setting of ``image.subtract_background`` (noise floor, thresholds, opening, closing),
the IoU of its masks with ``DIR/truth.npz``'s, and where the errors lie (within 2 pixels of the
true outline or away from it).
"""

import argparse
import json
import os

import numpy as np
from scipy import ndimage

from jaxtrack.image import fit_background, subtract_background
from jaxtrack.io import MultiViewVideo, load_sequence

SETTINGS = [  # (noise floor in levels of 255, low, high, opening radius, closing radius)
    (2, 4, 8, 1, 2), (2, 6, 12, 1, 1), (3, 4, 8, 1, 2), (3, 4, 8, 1, 1), (3, 6, 12, 1, 1),
    (3, 6, 12, 0, 1), (3, 8, 16, 1, 1), (3, 8, 16, 1, 2), (3, 8, 16, 0, 1), (3, 8, 16, 0, 2), (4, 8, 16, 0, 1)]


def read(paths) -> np.ndarray:
    with MultiViewVideo(paths) as video:
        return np.concatenate([c for _, c in video.chunks(64)], axis=1)  # (C, T, H, W, 3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("folder")
    parser.add_argument("--json", help="also write the rows as JSON here")
    args = parser.parse_args()
    truth = load_sequence(os.path.join(args.folder, "truth.npz"))
    names = [str(n) for n in truth.camera_names]
    empty = read([os.path.join(args.folder, "background", f"{n}.mp4") for n in names])
    frames = np.moveaxis(read([os.path.join(args.folder, f"{n}.mp4") for n in names]), 1, 0)
    true = truth.silhouettes.swapaxes(0, 1).astype(bool)  # (T, C, H, W)
    band = np.zeros_like(true)
    for index in np.ndindex(true.shape[:2]):
        band[index] = ndimage.binary_dilation(true[index], iterations=2) & ~ndimage.binary_erosion(true[index], iterations=2)
    rows = []
    for floor, low, high, opening, closing in SETTINGS:
        model = fit_background(np.moveaxis(empty, 1, 0), min_noise=floor / 255.0)
        mask = np.asarray(subtract_background(model, frames, low=low, high=high, open_radius=opening, close_radius=closing).mask)
        iou = (mask & true).sum(axis=(2, 3)) / (mask | true).sum(axis=(2, 3))
        away = (mask & true & ~band).sum(axis=(2, 3)) / ((mask | true) & ~band).sum(axis=(2, 3))
        wrong_fg, missed = mask & ~true, ~mask & true
        rows.append({"floor": floor, "low": low, "high": high, "opening": opening, "closing": closing,
                     "iou_mean": float(iou.mean()), "iou_worst": float(iou.min()),
                     "iou_away_from_outline": float(away.mean()), "iou_away_worst": float(away.min()),
                     "false_fg_per_frame": float(wrong_fg.sum() / len(mask)), "missed_per_frame": float(missed.sum() / len(mask)),
                     "false_fg_near_outline": float((wrong_fg & band).sum() / max(wrong_fg.sum(), 1)),
                     "missed_near_outline": float((missed & band).sum() / max(missed.sum(), 1))})
        r = rows[-1]
        print(f"floor {floor}, ({low}, {high}), open {opening}, close {closing}: IoU {r['iou_mean']:.3f} (worst {r['iou_worst']:.3f}); "
              f"away from the outline {r['iou_away_from_outline']:.3f}; false fg {r['false_fg_per_frame']:.0f} px/frame "
              f"({100 * r['false_fg_near_outline']:.0f} % near the outline), missed {r['missed_per_frame']:.0f} "
              f"({100 * r['missed_near_outline']:.0f} %)")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(rows, handle, indent=1)


if __name__ == "__main__":
    main()
