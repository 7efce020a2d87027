"""Merge the ten raw Stanford bunny range scans into one point set, placed by bun.conf.

usage: python merge_bunny_scans.py SCANS_DIR OUT.xyz   (needs numpy, scipy, open3d)

Each `bmesh FILE tx ty tz qx qy qz qw` line places FILE by p' = R(q)^-1 p + t
(checked: every scan then lies within ~5e-4 of bun_zipper.ply, median).
"""
import sys
import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

scans, out = sys.argv[1], sys.argv[2]
parts = []
for line in open(f"{scans}/bun.conf"):
    words = line.split()
    if not words or words[0] != "bmesh":
        continue
    t = np.array([float(w) for w in words[2:5]])
    q = np.array([float(w) for w in words[5:9]])
    p = np.asarray(o3d.io.read_point_cloud(f"{scans}/{words[1]}").points)
    parts.append(Rotation.from_quat(q).inv().apply(p) + t)
points = np.vstack(parts)
np.savetxt(out, points, fmt="%.7g")
print(out, len(points), "points")
