#!/usr/bin/env python3
"""OpenCV side of the NCC speed comparison.

Times cv2.matchTemplate(TM_CCOEFF_NORMED) + minMaxLoc, single thread, 8-bit, on
the images written by `cargo run --release -p vtsm-core --example bench_ncc -- --out DIR`
(256-in-800, 128-in-800, 64-in-200 and 32-in-96) and prints the same quantities as the Rust example (wall-clock median and thread
CPU time per match, best position and score). `vtsm bench` embeds this script, runs it on
the same images in a temporary directory and parses its output (`sim/src/cli/bench.rs`).

    pip install opencv-python-headless numpy
    python3 sim/bench/opencv_ncc.py DIR [--repeat N]
"""
import argparse
import pathlib
import statistics
import time

import cv2

cv2.setNumThreads(1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir", type=pathlib.Path)
    ap.add_argument("--repeat", type=int, default=21)
    a = ap.parse_args()
    print(f"# OpenCV {cv2.__version__}, threads={cv2.getNumThreads()}, "
          "TM_CCOEFF_NORMED + minMaxLoc")
    # (template side, image file, matches per timed sample) as in bench_ncc.rs
    for l, name, inner in ((256, "image.pgm", 1), (128, "image.pgm", 1),
                           (64, "image200.pgm", 10), (32, "image96.pgm", 50)):
        image = cv2.imread(str(a.dir / name), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise SystemExit(f"{a.dir / name}: cannot read")
        path = a.dir / f"t{l}.pgm"
        tpl = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if tpl is None:
            raise SystemExit(f"{path}: cannot read")
        times = []
        cpu0 = time.thread_time_ns()
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            for _ in range(inner):
                res = cv2.matchTemplate(image, tpl, cv2.TM_CCOEFF_NORMED)
                _, mx, _, loc = cv2.minMaxLoc(res)
            times.append((time.perf_counter() - t0) * 1e3 / inner)
        cpu_ms = (time.thread_time_ns() - cpu0) * 1e-6 / (a.repeat * inner)
        print(f"{l}-in-{image.shape[1]} OpenCV        ms_per_match {statistics.median(times):9.3f}  "
              f"cpu_ms_per_match {cpu_ms:9.3f}  at ({loc[0]},{loc[1]}) score {mx:.6f}")


if __name__ == "__main__":
    main()
