#!/usr/bin/env python3
"""OpenCV side of the NCC speed comparison.

Times cv2.matchTemplate(TM_CCOEFF_NORMED) + minMaxLoc, single thread, 8-bit, on
the images written by `cargo run --release -p vtsm-core --example bench_ncc -- --out DIR`
and prints the same quantities as the Rust example (wall-clock median and thread
CPU time per match, best position and score).

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
    image = cv2.imread(str(a.dir / "image.pgm"), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise SystemExit(f"{a.dir / 'image.pgm'}: cannot read")
    print(f"# OpenCV {cv2.__version__}, threads={cv2.getNumThreads()}, "
          f"image {image.shape[1]}x{image.shape[0]}, TM_CCOEFF_NORMED + minMaxLoc")
    for l in (256, 128):
        path = a.dir / f"t{l}.pgm"
        tpl = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if tpl is None:
            raise SystemExit(f"{path}: cannot read")
        times = []
        cpu0 = time.thread_time_ns()
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            res = cv2.matchTemplate(image, tpl, cv2.TM_CCOEFF_NORMED)
            _, mx, _, loc = cv2.minMaxLoc(res)
            times.append((time.perf_counter() - t0) * 1e3)
        cpu_ms = (time.thread_time_ns() - cpu0) * 1e-6 / a.repeat
        print(f"{l}-in-{image.shape[1]} OpenCV        ms_per_match {statistics.median(times):9.3f}  "
              f"cpu_ms_per_match {cpu_ms:9.3f}  at ({loc[0]},{loc[1]}) score {mx:.6f}")


if __name__ == "__main__":
    main()
