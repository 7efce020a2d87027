"""Python call overhead against the command line and the Rust work itself.

usage: python overhead.py MESH N RUNS CLI
Samples N points uniformly from MESH (seeded), writes them to a PLY, then
RUNS times each: `CLI reconstruct pts.ply -o out.ply` (wall clock), and
surfrecon.reconstruct(points) (wall clock of the call, and the time between
the facade's first and last progress report, i.e. the Rust run without the
array conversions). Prints one line per run and the medians.
"""

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import surfrecon


def sample(mesh_path, n, seed=0):
    m = surfrecon.read(mesh_path)
    V, F = m["vertices"], m["triangles"]
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    rng = np.random.default_rng(seed)
    t = rng.choice(len(F), n, p=area / area.sum())
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    return a[t] + u[:, None] * (b[t] - a[t]) + v[:, None] * (c[t] - a[t])


def main():
    mesh, n, runs, cli = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
    points = sample(mesh, n)
    tmp = Path(tempfile.mkdtemp())
    ply = tmp / "points.ply"
    surfrecon.write(ply, points)
    rows = []
    for i in range(runs):
        start = time.perf_counter()
        subprocess.run([cli, "--quiet", "reconstruct", str(ply), "-o", str(tmp / "cli.ply")], check=True)
        cli_wall = time.perf_counter() - start
        marks = {}

        def progress(stage, done, total):
            if stage in ("start", "done"):
                marks[stage] = time.perf_counter()

        start = time.perf_counter()
        V, F = surfrecon.reconstruct(points, progress=progress)
        py_wall = time.perf_counter() - start
        rust = marks["done"] - marks["start"]
        rows.append((cli_wall, py_wall, rust))
        print(f"run {i}: cli {cli_wall:.2f} s, python {py_wall:.2f} s, rust inside {rust:.2f} s, "
              f"python − rust {py_wall - rust:.3f} s ({100 * (py_wall - rust) / rust:.2f}%), "
              f"{len(F)} triangles", flush=True)
    med = [statistics.median(r[k] for r in rows) for k in range(3)]
    print(f"median: cli {med[0]:.2f} s, python {med[1]:.2f} s, rust inside {med[2]:.2f} s, "
          f"overhead {med[1] - med[2]:.3f} s ({100 * (med[1] - med[2]) / med[2]:.2f}%)")


if __name__ == "__main__":
    main()
