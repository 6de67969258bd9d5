"""Reference rectification with OpenCV, for sim/tests/rectify_cv2.rs.

usage: python3 cv2_rectify.py calib.json left.png right.png OUTDIR

Reads the OpenCV form of calib.json, runs cv2.stereoRectify (default flags,
i.e. CALIB_ZERO_DISPARITY, alpha=-1), cv2.initUndistortRectifyMap (CV_32FC1)
and cv2.remap (BORDER_CONSTANT 0) with INTER_LINEAR, INTER_CUBIC and INTER_LANCZOS4,
and writes OUTDIR/rect.json ({"R1","R2","P1","P2","version"}),
OUTDIR/{left,right}_rect_{linear,cubic,lanczos4}.png and the maps as raw
little-endian f32 (OUTDIR/{left,right}_map{x,y}.f32).
"""
import json
import sys

import cv2
import numpy as np


def main():
    calib_path, left_path, right_path, out = sys.argv[1:5]
    with open(calib_path) as f:
        c = json.load(f)
    size = tuple(c["image_size"])
    k1 = np.array(c["left"]["K"], dtype=np.float64)
    k2 = np.array(c["right"]["K"], dtype=np.float64)
    d1 = np.array(c["left"]["dist"], dtype=np.float64)
    d2 = np.array(c["right"]["dist"], dtype=np.float64)
    r = np.array(c["R"], dtype=np.float64)
    t = np.array(c["T"], dtype=np.float64).reshape(3, 1)
    r1, r2, p1, p2, _q, _roi1, _roi2 = cv2.stereoRectify(k1, d1, k2, d2, size, r, t)
    res = {"R1": r1.tolist(), "R2": r2.tolist(), "P1": p1.tolist(), "P2": p2.tolist(),
           "version": cv2.__version__}
    with open(f"{out}/rect.json", "w") as f:
        json.dump(res, f)
    for name, path, k, d, rr, p in (
        ("left", left_path, k1, d1, r1, p1),
        ("right", right_path, k2, d2, r2, p2),
    ):
        mx, my = cv2.initUndistortRectifyMap(k, d, rr, p, size, cv2.CV_32FC1)
        mx.astype("<f4").tofile(f"{out}/{name}_mapx.f32")
        my.astype("<f4").tofile(f"{out}/{name}_mapy.f32")
        img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        for kernel, flag in (("linear", cv2.INTER_LINEAR), ("cubic", cv2.INTER_CUBIC),
                             ("lanczos4", cv2.INTER_LANCZOS4)):
            rect = cv2.remap(img, mx, my, flag, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
            cv2.imwrite(f"{out}/{name}_rect_{kernel}.png", rect)


if __name__ == "__main__":
    main()
