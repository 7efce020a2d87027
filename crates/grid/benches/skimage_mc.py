"""Time scikit-image's marching_cubes on the field written by the
`marching` bench (raw little-endian f64, x fastest, N^3 nodes).

Usage: python skimage_mc.py FIELD.f64 N [runs]
Not a dependency of surfrecon: run it from a throwaway virtualenv with
numpy and scikit-image installed. Prints `seconds=<best> triangles=<count>`.
"""
import sys
import time

import numpy as np
from skimage import __version__ as skimage_version
from skimage.measure import marching_cubes


def main():
    path, n = sys.argv[1], int(sys.argv[2])
    runs = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    # x fastest on disk = C order (z, y, x).
    volume = np.fromfile(path, dtype="<f8").reshape((n, n, n))
    best, faces = float("inf"), None
    for _ in range(runs):
        start = time.perf_counter()
        verts, faces, normals, values = marching_cubes(volume, level=0.0)
        best = min(best, time.perf_counter() - start)
    print(f"seconds={best:.3f} triangles={len(faces)} skimage={skimage_version} dtype={volume.dtype}")


if __name__ == "__main__":
    main()
