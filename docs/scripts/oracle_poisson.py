"""Oracle baseline: Open3D screened Poisson given the true normals.

usage: python oracle_poisson.py ORACLE.xyz OUT.ply DEPTH   (needs numpy, open3d)
"""
import sys, numpy as np, open3d as o3d
D=np.loadtxt(sys.argv[1]); pc=o3d.geometry.PointCloud(o3d.utility.Vector3dVector(D[:,:3])); pc.normals=o3d.utility.Vector3dVector(D[:,3:6])
m,_=o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(pc, depth=int(sys.argv[3]), scale=1.1, linear_fit=False)
o3d.io.write_triangle_mesh(sys.argv[2], m)
