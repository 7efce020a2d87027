#!/usr/bin/env python3
"""Write the committed seed corpora in fuzz/corpus-seeds/<target>/: small
valid files of every variant each reader accepts. Re-run after a format
changes: `python3 fuzz/make_seeds.py` (overwrites the seeds)."""
import gzip, os, struct, sys

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus-seeds")

def put(target, name, data):
    d = os.path.join(ROOT, target)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)

# A tetrahedron: 4 vertices, 4 faces; normals and a scalar per vertex.
V = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
N = [(-0.577, -0.577, -0.577), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
S = [0.5, 1.0, 0.25, 2.0]
F = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]

# ---- PLY ----
def ply(encoding, normals=False, scalar=None, faces=True, quad=False,
        range_grid=False, vtype="float", itype="int", ctype="uchar", extra=False):
    h = ["ply", f"format {encoding} 1.0", "comment seed", f"element vertex {len(V)}",
         f"property {vtype} x", f"property {vtype} y", f"property {vtype} z"]
    if normals:
        h += [f"property {vtype} nx", f"property {vtype} ny", f"property {vtype} nz"]
    if scalar:
        h.append(f"property float {scalar}")
    if extra:
        h.append("property uchar red")
    fs = [(0, 1, 2, 3)] + F[1:] if quad else F
    if faces:
        h += [f"element face {len(fs)}", f"property list {ctype} {itype} vertex_indices"]
    if range_grid:
        h += ["element range_grid 2", "property list uchar int vertex_indices"]
    h.append("end_header")
    head = ("\n".join(h) + "\n").encode()
    rows = []
    for i, v in enumerate(V):
        r = list(v) + (list(N[i]) if normals else []) + ([S[i]] if scalar else []) + ([7] if extra else [])
        rows.append(r)
    if encoding == "ascii":
        body = "".join(" ".join(repr(x) if isinstance(x, float) else str(x) for x in r) + "\n" for r in rows)
        if faces:
            body += "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in fs)
        if range_grid:
            body += "1 0\n1 1\n"
        return head + body.encode()
    e = "<" if encoding == "binary_little_endian" else ">"
    vf = {"float": "f", "double": "d"}[vtype]
    out = bytearray(head)
    for r in rows:
        nf = len(r) - (1 if extra else 0)
        out += struct.pack(e + vf * (nf - (1 if scalar else 0)), *r[:nf - (1 if scalar else 0)])
        if scalar:
            out += struct.pack(e + "f", r[nf - 1])
        if extra:
            out += struct.pack(e + "B", 7)
    cf = {"uchar": "B", "int": "i"}[ctype]
    if_ = {"int": "i", "uint": "I", "short": "h"}[itype]
    if faces:
        for f in fs:
            out += struct.pack(e + cf + if_ * len(f), len(f), *f)
    if range_grid:
        out += struct.pack(e + "Bi", 1, 0) + struct.pack(e + "Bi", 1, 1)
    return bytes(out)

put("ply", "ascii_mesh.ply", ply("ascii"))
put("ply", "ascii_normals_quality.ply", ply("ascii", normals=True, scalar="quality"))
put("ply", "ascii_points_only.ply", ply("ascii", faces=False, scalar="confidence"))
put("ply", "ascii_quad_extra.ply", ply("ascii", quad=True, extra=True))
put("ply", "le_mesh.ply", ply("binary_little_endian"))
put("ply", "le_normals_intensity.ply", ply("binary_little_endian", normals=True, scalar="intensity"))
put("ply", "le_double_uint.ply", ply("binary_little_endian", vtype="double", itype="uint"))
put("ply", "be_mesh_normals.ply", ply("binary_big_endian", normals=True))
put("ply", "be_range_grid.ply", ply("binary_big_endian", faces=False, range_grid=True, scalar="scalar_x"))
put("ply", "ascii_range_grid.ply", ply("ascii", faces=False, range_grid=True))
put("ply", "le_short_int_counts.ply", ply("binary_little_endian", itype="short", ctype="int", scalar="value"))
put("ply", "planar_xy.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nelement face 1\nproperty list uchar int vertex_index\nend_header\n0 0\n1 0\n0 1\n3 0 1 2\n")

# ---- OBJ ----
put("obj", "mesh.obj", "# tetrahedron\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in V) + "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in F))
put("obj", "negative_indices_quad.obj", "o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4 -3 -2 -1\n")
put("obj", "normals_texture.obj", "mtllib x.mtl\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in V)
    + "".join(f"vn {x} {y} {z}\n" for x, y, z in N) + "vt 0 0\nvt 1 0\nvt 0 1\n"
    + "g tet\nusemtl m\ns 1\nf 1/1/1 3/3/3 2/2/2\nf 1//1 2//2 4//4\nf 1/1 4/2 3/3\nf 2 3 4\n")
put("obj", "polylines.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 1\nl 1 2 3 4\nl -1 -4\n# comment at end\n")
put("obj", "points_only.obj", "# cloud\nv 0.5 0.25 1e-3\nv -1 2 3\nv 1e10 -1e-10 0\n")
put("obj", "vertex_colors_crlf.obj", "v 0 0 0 1 0 0\r\nv 1 0 0 0 1 0\r\nv 0 1 0 0 0 1\r\nf 1 2 3\r\n")

# ---- OFF ----
put("off", "mesh.off", "OFF\n# tetra\n4 4 6\n" + "".join(f"{x} {y} {z}\n" for x, y, z in V) + "".join(f"3 {a} {b} {c}\n" for a, b, c in F))
put("off", "quad_colors.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 255 0 0\n")
put("off", "noff_normals.off", "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n")
put("off", "points_only.off", "OFF 3 0 0\n0 0 0\n1 2 3\n-1 -2 -3\n")
put("off", "coff.off", "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n3 0 1 2\n")

# ---- STL ----
def stl_ascii(name="tet"):
    s = f"solid {name}\n"
    for a, b, c in F:
        s += "  facet normal 0 0 0\n    outer loop\n"
        for i in (a, b, c):
            s += "      vertex {} {} {}\n".format(*V[i])
        s += "    endloop\n  endfacet\n"
    return s + f"endsolid {name}\n"
def stl_binary(header=b"binary seed"):
    out = bytearray(header.ljust(80, b" "))
    out += struct.pack("<I", len(F))
    for a, b, c in F:
        out += struct.pack("<3f", 0, 0, 0)
        for i in (a, b, c):
            out += struct.pack("<3f", *V[i])
        out += struct.pack("<H", 0)
    return bytes(out)
put("stl", "ascii.stl", stl_ascii())
put("stl", "ascii_unnamed_one.stl", "solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n")
put("stl", "binary.stl", stl_binary())
put("stl", "binary_header_says_solid.stl", stl_binary(b"solid but binary"))

# ---- XYZ ----
put("xyz", "cols2.xyz", "0 0\n1 0\n0.5 1\n")
put("xyz", "cols3.xyz", "# x y z\n" + "".join(f"{x} {y} {z}\n" for x, y, z in V))
put("xyz", "cols4_scalar.xyz", "".join(f"{x} {y} {z} {s}\n" for (x, y, z), s in zip(V, S)))
put("xyz", "cols6_normals.xyz", "".join("{} {} {} {} {} {}\n".format(*v, *n) for v, n in zip(V, N)))
put("xyz", "cols7_commas.xyz", "".join("{},{},{},{},{},{},{}\n".format(*v, *n, s) for v, n, s in zip(V, N, S)))
put("xyz", "semicolons_blank_crlf.xyz", "1;2;3\r\n\r\n4;5;6\r\n# end\r\n")

# ---- NRRD / VTK: 3x3x2 and 3x2 fields ----
vals3 = [0.1 * i - 0.5 for i in range(18)]
vals2 = [0.25 * i - 0.5 for i in range(6)]
def nrrd(dims, vals, typ="double", enc="raw", endian="little", spacing="dirs"):
    d = len(dims)
    h = ["NRRD0004", "# seed", f"type: {typ}", f"dimension: {d}", f"sizes: {' '.join(map(str, dims))}"]
    if spacing == "dirs":
        h += [f"space dimension: {d}",
              "space directions: " + " ".join("(" + ",".join("0.5" if a == b else "0" for b in range(d)) + ")" for a in range(d)),
              "space origin: (" + ",".join(["1.5", "-2", "0.25"][:d]) + ")"]
    elif spacing == "spacings":
        h.append("spacings: " + " ".join(["0.5"] * d))
    h += ["kinds: " + " ".join(["domain"] * d), f"endian: {endian}", f"encoding: {enc}", "key:=value"]
    head = ("\n".join(h) + "\n\n").encode()
    if enc in ("ascii", "text"):
        return head + (" ".join(repr(v) for v in vals) + "\n").encode()
    f = {"double": "d", "float": "f"}[typ]
    raw = struct.pack(("<" if endian == "little" else ">") + f * len(vals), *vals)
    return head + (gzip.compress(raw, mtime=0) if enc == "gzip" else raw)
put("nrrd", "d3_double_raw_le.nrrd", nrrd([3, 3, 2], vals3))
put("nrrd", "d3_float_raw_be.nrrd", nrrd([3, 3, 2], vals3, typ="float", endian="big"))
put("nrrd", "d3_double_gzip.nrrd", nrrd([3, 3, 2], vals3, enc="gzip"))
put("nrrd", "d3_ascii_spacings.nrrd", nrrd([3, 3, 2], vals3, enc="ascii", spacing="spacings"))
put("nrrd", "d2_double_raw.nrrd", nrrd([3, 2], vals2))
put("nrrd", "d2_float_text_nospacing.nrrd", nrrd([3, 2], vals2, typ="float", enc="text", spacing=None))

def vtk(dims, vals, binary=True, typ="double"):
    n = dims[0] * dims[1] * dims[2]
    h = ["# vtk DataFile Version 3.0", "seed field", "BINARY" if binary else "ASCII",
         "DATASET STRUCTURED_POINTS", "DIMENSIONS " + " ".join(map(str, dims)),
         "ORIGIN 1.5 -2 0.25" if dims[2] > 1 else "ORIGIN 1.5 -2 0", "SPACING 0.5 0.5 0.5",
         f"POINT_DATA {n}", f"SCALARS values {typ} 1", "LOOKUP_TABLE default"]
    head = ("\n".join(h) + "\n").encode()
    if not binary:
        return head + ("\n".join(repr(v) for v in vals) + "\n").encode()
    f = {"double": "d", "float": "f"}[typ]
    return head + struct.pack(">" + f * len(vals), *vals) + b"\n"
put("vtk", "d3_binary_double.vtk", vtk([3, 3, 2], vals3))
put("vtk", "d3_binary_float.vtk", vtk([3, 3, 2], vals3, typ="float"))
put("vtk", "d3_ascii_double.vtk", vtk([3, 3, 2], vals3, binary=False))
put("vtk", "d2_binary_double.vtk", vtk([3, 2, 1], vals2))
put("vtk", "d2_ascii_float.vtk", vtk([3, 2, 1], vals2, binary=False, typ="float"))

# ---- thin shell (SRSHELL\0, version 1) ----
def varint(x):
    out = bytearray()
    while x >= 0x80:
        out.append((x & 0x7f) | 0x80); x >>= 7
    out.append(x)
    return bytes(out)
def shell(dims, origin, spacing, indices, values):
    out = bytearray(b"SRSHELL\0") + struct.pack("<II", 1, len(dims))
    out += b"".join(struct.pack("<Q", n) for n in dims)
    out += b"".join(struct.pack("<d", o) for o in origin) + struct.pack("<d", spacing)
    out += struct.pack("<Q", len(indices))
    prev = 0
    for l in indices:
        out += varint(l - prev); prev = l
    out += b"".join(struct.pack("<d", v) for v in values)
    return bytes(out)
put("shell", "d3.shell", shell([4, 4, 4], [0, 0, 0], 0.5, [5, 6, 9, 10, 21, 22, 42, 63],
                                [-0.1, 0.2, 0.05, -0.3, 0.1, -0.1, 0.4, 0.2]))
put("shell", "d2.shell", shell([3, 5], [-1.0, 2.0], 0.25, [0, 4, 7, 14], [0.1, -0.2, 0.0, 0.3]))
put("shell", "d3_big_index.shell", shell([300, 2, 2], [1.0, 1.0, 1.0], 2.0, [1, 200, 1199], [0.5, -0.5, 1.0]))
put("shell", "d3_empty.shell", shell([2, 2, 2], [0, 0, 0], 1.0, [], []))

# ---- .svm model (SRSVMMDL, version 1) ----
def svm(offset, levels):
    out = bytearray(b"SRSVMMDL") + struct.pack("<Id", 1, offset) + struct.pack("<I", len(levels))
    for width, centres in levels:
        out += struct.pack("<dQ", width, len(centres))
        for c in centres:
            out += struct.pack("<4d", *c)
    return bytes(out)
put("svm", "two_levels.svm", svm(-0.5, [(2.0, [(0, 0, 0, 1.0), (1, 0, 0, -0.5)]), (0.5, [(0.1, 0.2, 0.3, 0.25), (-1, -1, 2, 0.125), (0, 0, 0, -1.0)])]))
put("svm", "one_level.svm", svm(0.0, [(1.0, [(0.5, 0.5, 0.5, 1.0)])]))
put("svm", "no_levels.svm", svm(1.0, []))
put("svm", "empty_level.svm", svm(0.25, [(3.0, [])]))

# ---- .odf / .udf (2x2x2 grid, spacing 0.5, origin (1,2,3)) ----
g_vals = [-0.2, 0.3, 0.1, -0.1, 0.4, 0.25, -0.05, 0.15]
def header(magic, dims=(2, 2, 2), origin=(1.0, 2.0, 3.0), spacing=0.5, vals=g_vals):
    return magic + struct.pack("<3I", *dims) + struct.pack("<3d", *origin) + struct.pack("<d", spacing) + struct.pack(f"<{len(vals)}d", *vals)
def node(i, dims=(2, 2, 2), origin=(1.0, 2.0, 3.0), h=0.5):
    x, y, z = i % dims[0], (i // dims[0]) % dims[1], i // (dims[0] * dims[1])
    return (origin[0] + h * x, origin[1] + h * y, origin[2] + h * z)
ODF = b"SRODF\0\0\x01"
UDF = b"SRUDF\0\0\x01"
put("odf", "none_moved.odf", header(ODF) + struct.pack("<Q", 0))
moved = [(1, 0.1), (6, -0.2)]
put("odf", "two_moved.odf", header(ODF) + struct.pack("<Q", len(moved)) + b"".join(
    struct.pack("<I3d", i, *(c + d for c in node(i))) for i, d in moved))
put("udf", "untagged.udf", header(UDF) + bytes(2))
tags = {0: 1, 3: 2, 5: 3}
tb = bytearray(2)
for i, t in tags.items():
    tb[i // 4] |= t << (2 * (i % 4))
extra = struct.pack("<3d", 0.2, float("inf"), 0.5) + struct.pack("<3d", 7.0, -3.0, 1e5) + struct.pack("<3d", *(c + 0.1 for c in node(5)))
put("udf", "all_tags.udf", header(UDF) + bytes(tb) + extra)
print("seeds written to", ROOT)
