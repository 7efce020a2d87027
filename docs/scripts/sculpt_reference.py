"""Exact mesh booleans to score `surfrecon sculpt` against.

Usage (any venv with numpy, trimesh and manifold3d, e.g. the bench
harness's .venv; not a project dependency):

    python sculpt_reference.py fandisk.off out.ply subtract sphere 2.5 15.5 -1.3 1.0
    python sculpt_reference.py box.ply out.ply subtract cylinder 0 0 -1 0 0 1 0.2

The tool is tessellated finely (sphere: 40k triangles, cylinder: 512
segments) so the reference's own faceting stays far below a grid cell.
"""
import sys

import manifold3d as m3d
import numpy as np
import trimesh


def to_manifold(mesh):
    return m3d.Manifold(m3d.Mesh(vert_properties=np.asarray(mesh.vertices, np.float32),
                                 tri_verts=np.asarray(mesh.faces, np.uint32)))


def tool(kind, v):
    if kind == "sphere":
        s = trimesh.creation.icosphere(subdivisions=6, radius=v[3])
        s.apply_translation(v[:3])
        return s
    if kind == "cylinder":
        a, b, r = np.array(v[:3]), np.array(v[3:6]), v[6]
        return trimesh.creation.cylinder(radius=r, segment=np.stack([a, b]), sections=512)
    if kind == "box":
        lo, hi = np.array(v[:3]), np.array(v[3:6])
        return trimesh.creation.box(bounds=np.stack([lo, hi]))
    raise SystemExit(f"unknown tool {kind}")


def main():
    src, out, op, kind, *nums = sys.argv[1:]
    obj = to_manifold(trimesh.load(src, process=False))
    t = to_manifold(tool(kind, [float(x) for x in nums]))
    result = {"subtract": obj - t, "union": obj + t, "intersect": obj ^ t}[op]
    mesh = result.to_mesh()
    trimesh.Trimesh(mesh.vert_properties[:, :3], mesh.tri_verts, process=False).export(out)


if __name__ == "__main__":
    main()
