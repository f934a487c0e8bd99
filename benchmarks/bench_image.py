"""Speed of jaxtrack.image on one frame of several views (default 3 views of 320x240), jitted:
compile time (first call) apart from the steady state (median of repeated calls), each against
SciPy's same operation run in the same process (``ratio`` = SciPy's time / ours; above 1 we are
faster). Background subtraction has no SciPy counterpart and reports its time alone.

    taskset -c 0,1 python benchmarks/bench_image.py --json image.json
"""

from __future__ import annotations

import argparse
import json
import time

from bench_output import add_output_arguments, median_seconds, pin_threads, write_json


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--views", type=int, default=3)
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--repeats", type=int, default=7)
    add_output_arguments(parser)
    args = parser.parse_args()
    pin_threads(args.threads)
    import jax
    import numpy as np
    from scipy import ndimage

    from jaxtrack import image

    rng = np.random.default_rng(0)
    shape = (args.views, args.height, args.width)
    grey = ndimage.gaussian_filter(rng.random(shape), (0, 4, 4)).astype(np.float32)
    edges = rng.random(shape) < 0.01
    rgb = (rng.random((9,) + shape + (3,)) * 255).astype(np.uint8)
    model = image.fit_background(rgb)
    cases = {
        "gaussian_blur sigma 2": (lambda x: image.gaussian_blur(x, 2.0), grey,
                                  lambda: [ndimage.gaussian_filter(v, 2.0) for v in grey]),
        "sobel": (image.sobel, grey, lambda: [(ndimage.sobel(v, 1), ndimage.sobel(v, 0)) for v in grey]),
        "distance_transform": (image.distance_transform, edges, lambda: [ndimage.distance_transform_edt(~v) for v in edges]),
        "canny_edges": (image.canny_edges, grey, None),
        "edge_proximity of canny": (lambda x: image.edge_proximity(image.canny_edges(x)), grey, None),
        "subtract_background": (lambda x: image.subtract_background(model, x).mask, rgb[0], None),
    }
    rows = []
    for name, (fn, data, reference) in cases.items():
        compiled = jax.jit(fn)
        start = time.perf_counter()
        jax.block_until_ready(compiled(data))
        first = time.perf_counter() - start
        steady = median_seconds(lambda f=compiled, x=data: jax.block_until_ready(f(x)), args.repeats)
        row = {"operation": name, "views": args.views, "size": f"{args.width}x{args.height}", "compile_s": round(first - steady, 3),
               "ms_per_frame": round(1000 * steady, 2)}
        if reference is not None:
            scipy_s = median_seconds(reference, args.repeats)
            row.update(scipy_ms=round(1000 * scipy_s, 2), ratio=round(scipy_s / steady, 2))
        rows.append(row)
        print(json.dumps(row), flush=True)
    write_json(rows, args.json)


if __name__ == "__main__":
    main()
