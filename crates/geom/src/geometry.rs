//! Point clouds, polylines, triangle meshes, and the [`Geometry`] a file holds.

use crate::Aabb;
use glam::DVec3;

/// Scattered points. Invariant: `normals` and `scalars`, when present, have
/// one entry per position.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    pub positions: Vec<DVec3>,
    /// Unit normals (or `None` when the input had none).
    pub normals: Option<Vec<DVec3>>,
    /// One optional scalar per point (e.g. scanner confidence).
    pub scalars: Option<Vec<f64>>,
}

impl PointCloud {
    pub fn new(positions: Vec<DVec3>) -> Self {
        PointCloud {
            positions,
            normals: None,
            scalars: None,
        }
    }

    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(&self.positions)
    }
}

/// Curves as chains of indices into a shared vertex list. Invariant: every
/// index is `< vertices.len()`; a closed curve repeats its first index last.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Polylines {
    pub vertices: Vec<DVec3>,
    pub lines: Vec<Vec<u32>>,
}

impl Polylines {
    /// All segments as vertex-index pairs.
    pub fn segments(&self) -> impl Iterator<Item = [u32; 2]> + '_ {
        self.lines
            .iter()
            .flat_map(|l| l.windows(2).map(|w| [w[0], w[1]]))
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(&self.vertices)
    }
}

/// Indexed triangle mesh. Invariant: every index is `< vertices.len()`;
/// `normals`, when present, has one unit normal per vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
    pub normals: Option<Vec<DVec3>>,
}

impl TriMesh {
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(&self.vertices)
    }

    /// Corner positions of triangle `t`.
    pub fn corners(&self, t: usize) -> [DVec3; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }

    /// Add `other`'s vertices and triangles (renumbered) to this mesh;
    /// vertex normals are kept only if both meshes have them.
    pub fn append(&mut self, other: &TriMesh) {
        let offset = self.vertices.len() as u32;
        self.vertices.extend(&other.vertices);
        (self.triangles).extend(other.triangles.iter().map(|t| t.map(|i| i + offset)));
        self.normals = match (self.normals.take(), &other.normals) {
            (Some(mut mine), Some(theirs)) => {
                mine.extend(theirs);
                Some(mine)
            }
            _ => None,
        };
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.corners(t);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// The mesh without its specks: connected pieces (through shared
    /// vertices) whose bounding-box diagonal is below `min_extent`; with
    /// how many were removed. Vertices are renumbered in their old order.
    pub fn without_specks(&self, min_extent: f64) -> (TriMesh, usize) {
        self.retain_pieces(|bounds, _| bounds.diagonal() >= min_extent)
    }

    /// The connected piece (through shared vertices) of every vertex,
    /// numbered 0.. in the order of their first vertex, with the number of
    /// pieces; vertices in no triangle are pieces of their own.
    pub fn piece_labels(&self) -> (Vec<usize>, usize) {
        let mut sets = crate::disjoint_sets::DisjointSets::new(self.vertices.len());
        for &[a, b, c] in &self.triangles {
            sets.union(a as usize, b as usize);
            sets.union(b as usize, c as usize);
        }
        let mut label_of_root = vec![usize::MAX; self.vertices.len()];
        let mut count = 0;
        let labels = (0..self.vertices.len())
            .map(|v| {
                let root = sets.find(v);
                if label_of_root[root] == usize::MAX {
                    label_of_root[root] = count;
                    count += 1;
                }
                label_of_root[root]
            })
            .collect();
        (labels, count)
    }

    /// The number of connected pieces made of triangles.
    pub fn piece_count(&self) -> usize {
        let (labels, _) = self.piece_labels();
        let mut used: Vec<usize> = self
            .triangles
            .iter()
            .map(|t| labels[t[0] as usize])
            .collect();
        used.sort_unstable();
        used.dedup();
        used.len()
    }

    /// The mesh with only the connected pieces (through shared vertices)
    /// for which `keep(bounding box, vertex positions)` holds; with how many
    /// were removed. Vertices are renumbered in their old order.
    pub fn retain_pieces(&self, keep: impl Fn(&Aabb, &[DVec3]) -> bool) -> (TriMesh, usize) {
        let (root, _) = self.piece_labels();
        let mut pieces: std::collections::HashMap<usize, (Aabb, Vec<DVec3>)> = Default::default();
        let mut seen = vec![false; self.vertices.len()];
        for &v in self.triangles.iter().flatten() {
            let v = v as usize;
            if !std::mem::replace(&mut seen[v], true) {
                let piece = pieces.entry(root[v]).or_insert((Aabb::EMPTY, Vec::new()));
                piece.0 = piece.0.grow(self.vertices[v]);
                piece.1.push(self.vertices[v]);
            }
        }
        let large: std::collections::HashSet<usize> = pieces
            .iter()
            .filter(|(_, (bounds, vertices))| keep(bounds, vertices))
            .map(|(&r, _)| r)
            .collect();
        let specks = pieces.len() - large.len();
        if specks == 0 {
            return (self.clone(), 0);
        }
        let kept = |v: usize| large.contains(&root[v]);
        let mut new_index = vec![u32::MAX; self.vertices.len()];
        let mut mesh = TriMesh::default();
        for v in (0..self.vertices.len()).filter(|&v| kept(v)) {
            new_index[v] = mesh.vertices.len() as u32;
            mesh.vertices.push(self.vertices[v]);
        }
        mesh.normals = self
            .normals
            .as_ref()
            .map(|n| (0..n.len()).filter(|&v| kept(v)).map(|v| n[v]).collect());
        mesh.triangles = self
            .triangles
            .iter()
            .filter(|t| kept(t[0] as usize))
            .map(|t| t.map(|v| new_index[v as usize]))
            .collect();
        (mesh, specks)
    }
}

/// Everything one file can hold: vertices (with optional per-vertex normals
/// and scalars), triangles and polylines over those vertices. A point cloud
/// is a geometry without triangles or lines.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Geometry {
    pub points: PointCloud,
    pub triangles: Vec<[u32; 3]>,
    pub lines: Vec<Vec<u32>>,
}

impl Geometry {
    pub fn from_mesh(mesh: TriMesh) -> Self {
        Geometry {
            points: PointCloud {
                positions: mesh.vertices,
                normals: mesh.normals,
                scalars: None,
            },
            triangles: mesh.triangles,
            lines: Vec::new(),
        }
    }

    pub fn from_points(points: PointCloud) -> Self {
        Geometry {
            points,
            ..Default::default()
        }
    }

    pub fn from_polylines(p: Polylines) -> Self {
        Geometry {
            points: PointCloud::new(p.vertices),
            triangles: Vec::new(),
            lines: p.lines,
        }
    }

    pub fn is_mesh(&self) -> bool {
        !self.triangles.is_empty()
    }

    pub fn bounds(&self) -> Aabb {
        self.points.bounds()
    }

    /// The triangles with their vertices (vertices used by no triangle stay).
    pub fn to_mesh(&self) -> TriMesh {
        TriMesh {
            vertices: self.points.positions.clone(),
            triangles: self.triangles.clone(),
            normals: self.points.normals.clone(),
        }
    }

    pub fn to_polylines(&self) -> Polylines {
        Polylines {
            vertices: self.points.positions.clone(),
            lines: self.lines.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::icosphere;

    #[test]
    fn an_appended_mesh_keeps_its_triangles_and_drops_unmatched_normals() {
        let a = icosphere(DVec3::ZERO, 1.0, 2);
        let b = icosphere(DVec3::new(3.0, 0.0, 0.0), 0.5, 1);
        let mut both = a.clone();
        both.append(&b);
        assert_eq!(both.vertices.len(), a.vertices.len() + b.vertices.len());
        assert_eq!(both.triangles.len(), a.triangles.len() + b.triangles.len());
        let last = both.triangles.len() - 1;
        assert_eq!(both.corners(last), b.corners(b.triangles.len() - 1));
        assert!((both.area() - a.area() - b.area()).abs() < 1e-12);
        let with_normals = |m: &TriMesh| TriMesh {
            normals: Some(m.vertices.clone()),
            ..m.clone()
        };
        let mut one_side = with_normals(&a);
        one_side.append(&TriMesh {
            normals: None,
            ..b.clone()
        });
        assert!(one_side.normals.is_none());
        let mut two_sides = with_normals(&a);
        two_sides.append(&with_normals(&b));
        assert_eq!(
            two_sides.normals.map(|n| n.len()),
            Some(both.vertices.len())
        );
    }

    #[test]
    fn specks_are_removed_and_the_rest_kept_whole() {
        let body = icosphere(DVec3::ZERO, 1.0, 3);
        let mut mesh = body.clone();
        for (centre, radius) in [(DVec3::splat(3.0), 0.01), (DVec3::splat(-3.0), 0.02)] {
            let speck = icosphere(centre, radius, 1);
            let offset = mesh.vertices.len() as u32;
            mesh.vertices.extend(speck.vertices);
            mesh.triangles
                .extend(speck.triangles.iter().map(|t| t.map(|v| v + offset)));
        }
        let (clean, removed) = mesh.without_specks(0.1);
        assert_eq!(removed, 2);
        assert_eq!(clean.vertices, body.vertices);
        assert_eq!(clean.triangles, body.triangles);
        // Nothing under the size: the mesh comes back as it was.
        assert_eq!(mesh.without_specks(0.01), (mesh.clone(), 0));
    }
}
