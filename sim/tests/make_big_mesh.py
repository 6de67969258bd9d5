#!/usr/bin/env python3
"""Write a large textured OBJ for measuring `vtsm map build` (not checked in).

Usage: make_big_mesh.py NX NY OUTDIR

Writes OUTDIR/m.obj (a gently undulating NX x NY grid of 1 cm cells, two triangles
per cell, so 2*NX*NY triangles and (NX+1)*(NY+1) vertices, one `vt` per vertex),
OUTDIR/m.mtl and OUTDIR/tex.png (512 x 512 gray). Examples:
  make_big_mesh.py 2000 1250 /tmp/big5m   # 5,000,000 triangles (above the cap)
  make_big_mesh.py 2048 1024 /tmp/bigcap  # 4,194,304 = MAX_MAP_TRIANGLES
"""
import os
import sys

import numpy as np


def main():
    nx, ny, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    os.makedirs(out, exist_ok=True)
    import cv2

    y, x = np.mgrid[0:512, 0:512]
    tex = (128 + 60 * np.sin(x * 0.1) * np.cos(y * 0.07) + 30 * ((x // 16 + y // 16) % 2)).astype(np.uint8)
    cv2.imwrite(os.path.join(out, "tex.png"), tex)
    with open(os.path.join(out, "m.mtl"), "w") as f:
        f.write("newmtl ground\nmap_Kd tex.png\n")
    step = 0.01
    with open(os.path.join(out, "m.obj"), "w") as f:
        f.write("mtllib m.mtl\nusemtl ground\n")
        i = np.arange(nx + 1)
        for j in range(ny + 1):
            xs = i * step
            ys = np.full(nx + 1, j * step)
            zs = 0.05 * np.sin(xs * 0.7) * np.cos(ys * 0.9)
            f.write("".join(f"v {a:.4f} {b:.4f} {c:.5f}\n" for a, b, c in zip(xs, ys, zs)))
        for j in range(ny + 1):
            v = j / ny
            f.write("".join(f"vt {a / nx:.6f} {v:.6f}\n" for a in i))
        for j in range(ny):
            lines = []
            for k in range(nx):
                a = j * (nx + 1) + k + 1
                b, c, d = a + 1, a + nx + 2, a + nx + 1
                lines.append(f"f {a}/{a} {b}/{b} {c}/{c}\nf {a}/{a} {c}/{c} {d}/{d}\n")
            f.write("".join(lines))
    print(f"{out}/m.obj: {2 * nx * ny} triangles, {(nx + 1) * (ny + 1)} vertices")


if __name__ == "__main__":
    main()
