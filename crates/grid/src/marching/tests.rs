//! Topology and accuracy tests of marching cubes and squares.

use super::*;
use crate::{Field2, Field3, GridSpec};
use rand::{Rng, SeedableRng};
use std::collections::HashMap;
use surfrecon_geom::{DVec3, TriMesh};

/// Closed-surface facts about a mesh, computed by brute force.
#[derive(Debug)]
pub(crate) struct Topo {
    pub euler: i64,
    pub components: usize,
}

/// Asserts that `mesh` is closed, edge-manifold, consistently oriented and
/// vertex-manifold with no degenerate triangles, and returns its topology.
pub(crate) fn closed_manifold(mesh: &TriMesh) -> Topo {
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    for t in &mesh.triangles {
        assert!(
            t[0] != t[1] && t[1] != t[2] && t[0] != t[2],
            "repeated index {t:?}"
        );
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        assert!(
            (b - a).cross(c - a).length() > 0.0,
            "zero-area triangle {t:?}"
        );
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "directed edge {a}->{b} used {n} times");
        assert_eq!(
            directed.get(&(b, a)),
            Some(&1),
            "edge {a}-{b} is a border or non-manifold"
        );
    }
    assert_vertex_manifold(mesh);
    let used: std::collections::HashSet<u32> = mesh.triangles.iter().flatten().copied().collect();
    let (v, e, f) = (
        used.len() as i64,
        (directed.len() / 2) as i64,
        mesh.triangles.len() as i64,
    );
    Topo {
        euler: v - e + f,
        components: components(mesh),
    }
}

/// The triangles around every vertex form one fan (a single cycle of link edges).
fn assert_vertex_manifold(mesh: &TriMesh) {
    let mut link: HashMap<u32, HashMap<u32, u32>> = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[(k + 1) % 3], t[(k + 2) % 3]);
            assert!(link.entry(t[k]).or_default().insert(a, b).is_none());
        }
    }
    for (v, next) in &link {
        let start = *next.keys().next().unwrap();
        let (mut cur, mut steps) = (start, 0);
        loop {
            cur = next[&cur];
            steps += 1;
            if cur == start {
                break;
            }
        }
        assert_eq!(steps, next.len(), "vertex {v} is not manifold");
    }
}

fn components(mesh: &TriMesh) -> usize {
    let mut parent: Vec<usize> = (0..mesh.vertices.len()).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for t in &mesh.triangles {
        for k in 1..3 {
            let (a, b) = (
                find(&mut parent, t[0] as usize),
                find(&mut parent, t[k] as usize),
            );
            parent[a] = b;
        }
    }
    let roots: std::collections::HashSet<usize> = mesh
        .triangles
        .iter()
        .map(|t| find(&mut parent, t[0] as usize))
        .collect();
    roots.len()
}

pub(crate) fn cube_spec(n: usize, lo: f64, hi: f64) -> GridSpec<3> {
    GridSpec {
        origin: [lo; 3],
        spacing: (hi - lo) / (n - 1) as f64,
        dims: [n; 3],
    }
}

pub(crate) fn sample3(spec: GridSpec<3>, f: impl Fn(DVec3) -> f64) -> Field3 {
    let values = (0..spec.node_count())
        .map(|l| f(DVec3::from_array(spec.position(spec.unlinear(l)))))
        .collect();
    Field3 { spec, values }
}

fn sphere_sdf(c: DVec3, r: f64) -> impl Fn(DVec3) -> f64 {
    move |p| (p - c).length() - r
}

fn torus_sdf(major: f64, minor: f64) -> impl Fn(DVec3) -> f64 {
    move |p| {
        let q = (p.x * p.x + p.y * p.y).sqrt() - major;
        (q * q + p.z * p.z).sqrt() - minor
    }
}

#[test]
fn sphere_is_closed_genus_zero_and_accurate() {
    let spec = cube_spec(48, -1.0, 1.0);
    let c = DVec3::new(0.013, -0.021, 0.007);
    let r = 0.7;
    let mesh = marching_cubes(&sample3(spec, sphere_sdf(c, r)), 0.0);
    let topo = closed_manifold(&mesh);
    assert_eq!((topo.euler, topo.components), (2, 1));
    let h = spec.spacing;
    let worst = mesh
        .vertices
        .iter()
        .map(|p| ((*p - c).length() - r).abs())
        .fold(0.0, f64::max);
    assert!(worst < 0.01 * h, "vertex off the sphere by {} h", worst / h);
    // Normals point outward, and triangles face the same way.
    let normals = mesh.normals.as_ref().unwrap();
    for (p, n) in mesh.vertices.iter().zip(normals) {
        assert!(n.dot((*p - c).normalize()) > 0.99);
    }
    for t in 0..mesh.triangles.len() {
        let [a, b, cc] = mesh.corners(t);
        assert!((b - a).cross(cc - a).dot((a + b + cc) / 3.0 - c) > 0.0);
    }
}

#[test]
fn torus_has_genus_one() {
    let spec = cube_spec(40, -1.0, 1.0);
    let mesh = marching_cubes(&sample3(spec, torus_sdf(0.55, 0.22)), 0.0);
    let topo = closed_manifold(&mesh);
    assert_eq!((topo.euler, topo.components), (0, 1));
}

#[test]
fn touching_and_nearly_touching_spheres() {
    let spec = cube_spec(41, -1.0, 1.0);
    let h = spec.spacing;
    for gap in [-0.5 * h, 0.0, 0.1 * h, 0.5 * h, 2.0 * h] {
        let r = 0.4;
        let a = DVec3::new(-r - gap / 2.0 + 0.003, 0.01, 0.0);
        let b = DVec3::new(r + gap / 2.0 + 0.003, 0.01, 0.0);
        let field = sample3(spec, |p| sphere_sdf(a, r)(p).min(sphere_sdf(b, r)(p)));
        let topo = closed_manifold(&marching_cubes(&field, 0.0));
        assert_eq!(topo.euler, 2 * topo.components as i64, "gap {gap}");
        if gap >= 0.5 * h {
            assert_eq!(topo.components, 2, "gap {gap}");
        }
        if gap < 0.0 {
            assert_eq!(topo.components, 1, "gap {gap}");
        }
    }
}

#[test]
fn random_smooth_fields_give_closed_manifolds() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    let spec = cube_spec(36, -1.0, 1.0);
    for _ in 0..6 {
        let bumps: Vec<(DVec3, f64, f64)> = (0..12)
            .map(|_| {
                let c = DVec3::new(
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-0.5..0.5),
                );
                (c, rng.random_range(0.1..0.25), rng.random_range(0.5..1.5))
            })
            .collect();
        let field = sample3(spec, |p| {
            bumps
                .iter()
                .map(|(c, s, a)| a * (-(p - *c).length_squared() / (s * s)).exp())
                .sum()
        });
        for iso in [0.3, 0.6] {
            let topo = closed_manifold(&marching_cubes(&field, iso));
            assert_eq!(topo.euler % 2, 0);
        }
    }
}

/// White noise is the worst case for ambiguity handling: nearly every
/// face and cell is ambiguous somewhere.
#[test]
fn noise_fields_with_values_at_iso_stay_manifold() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let spec = cube_spec(14, 0.0, 1.0);
    for levels in [None, Some(3)] {
        let values = (0..spec.node_count())
            .map(|l| {
                let on_boundary = spec.unlinear(l).iter().any(|&i| i == 0 || i == 13);
                match (on_boundary, levels) {
                    (true, _) => 1.0,
                    // {-1, 0, 1}: many nodes exactly at iso 0.
                    (false, Some(n)) => rng.random_range(0..n) as f64 - 1.0,
                    (false, None) => rng.random_range(-1.0..1.0),
                }
            })
            .collect();
        let field = Field3 { spec, values };
        let mesh = marching_cubes(&field, 0.0);
        assert!(!mesh.triangles.is_empty());
        let topo = closed_manifold(&mesh);
        assert_eq!(topo.euler % 2, 0);
        assert_weld_safe(&mesh, spec.spacing);
    }
}

/// No two vertices of a triangle closer than 1e-3 of a cell (vertices on
/// nodes at iso are kept off them), so welding close vertices with any
/// tolerance below that changes nothing.
fn assert_weld_safe(mesh: &TriMesh, h: f64) {
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
        let shortest = a.distance(b).min(b.distance(c)).min(c.distance(a));
        assert!(shortest >= 0.9e-3 * h, "edge of {shortest} (h = {h})");
    }
}

#[test]
fn open_surface_at_grid_boundary_and_empty_cases() {
    let spec = cube_spec(10, -1.0, 1.0);
    // A plane through the grid: a single open sheet.
    let mesh = marching_cubes(&sample3(spec, |p| p.z - 0.05), 0.0);
    assert_eq!(mesh.triangles.len(), 2 * 9 * 9);
    assert!(marching_cubes(&sample3(spec, |_| 1.0), 0.0)
        .triangles
        .is_empty());
    let tiny = Field3::filled(
        GridSpec {
            origin: [0.0; 3],
            spacing: 1.0,
            dims: [1, 5, 5],
        },
        -1.0,
    );
    assert!(marching_cubes(&tiny, 0.0).triangles.is_empty());
}

#[test]
fn output_does_not_depend_on_thread_count() {
    let spec = cube_spec(50, -1.0, 1.0);
    let field = sample3(spec, torus_sdf(0.5, 0.2));
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| marching_cubes(&field, 0.0))
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn case_table_has_all_cases() {
    // All 256 configurations with every face choice are triangulable.
    let t = tables::cube_table();
    let total: usize = (0..=255u8).map(|c| t.triangles(c, 0).len()).sum();
    assert!(total > 0);
}

fn sample2(spec: GridSpec<2>, mut f: impl FnMut(f64, f64) -> f64) -> Field2 {
    let values = (0..spec.node_count())
        .map(|l| {
            let p = spec.position(spec.unlinear(l));
            f(p[0], p[1])
        })
        .collect();
    Field2 { spec, values }
}

fn square_spec(n: usize) -> GridSpec<2> {
    GridSpec {
        origin: [-1.5; 2],
        spacing: 3.0 / (n - 1) as f64,
        dims: [n; 2],
    }
}

fn signed_area(lines: &surfrecon_geom::Polylines, line: &[u32]) -> f64 {
    line.windows(2)
        .map(|w| {
            let (a, b) = (lines.vertices[w[0] as usize], lines.vertices[w[1] as usize]);
            0.5 * (a.x * b.y - b.x * a.y)
        })
        .sum()
}

/// Every vertex is used by exactly one curve, once (twice as first/last of a closed one).
fn assert_all_closed(p: &surfrecon_geom::Polylines) {
    let mut uses = vec![0; p.vertices.len()];
    for l in &p.lines {
        assert!(l.len() >= 4 && l.first() == l.last(), "open curve {l:?}");
        for &v in &l[1..] {
            uses[v as usize] += 1;
        }
    }
    assert!(uses.iter().all(|&u| u == 1));
}

#[test]
fn circle_is_one_closed_counter_clockwise_curve() {
    let spec = square_spec(64);
    let (cx, cy, r) = (0.03, -0.02, 1.0);
    let p = marching_squares(&sample2(spec, |x, y| ((x - cx).hypot(y - cy)) - r), 0.0);
    assert_eq!(p.lines.len(), 1);
    assert_all_closed(&p);
    let area = signed_area(&p, &p.lines[0]);
    assert!(
        (area - std::f64::consts::PI * r * r).abs() < 0.01,
        "area {area}"
    );
    let h = spec.spacing;
    for v in &p.vertices {
        assert!(((v.x - cx).hypot(v.y - cy) - r).abs() < 0.01 * h);
    }
}

#[test]
fn saddles_give_closed_curves() {
    // Lemniscate-like field with a saddle exactly at iso at the origin.
    let spec = square_spec(61);
    let f = |x: f64, y: f64| (x * x + y * y).powi(2) - 2.0 * (x * x - y * y);
    for iso in [-0.3, 0.0, 0.3] {
        let p = marching_squares(&sample2(spec, f), iso);
        assert_all_closed(&p);
        // Below the saddle two lobes; above it one curve around both.
        match iso {
            i if i < 0.0 => assert_eq!(p.lines.len(), 2),
            i if i > 0.0 => assert_eq!(p.lines.len(), 1),
            _ => assert!(!p.lines.is_empty()),
        }
    }
    // Noise with a high border: many saddle cells, all curves closed.
    let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
    let spec = square_spec(30);
    let field = sample2(spec, |x, y| {
        if x.abs() > 1.45 || y.abs() > 1.45 {
            1.0
        } else {
            rng.random_range(-1.0..1.0)
        }
    });
    assert_all_closed(&marching_squares(&field, 0.0));
}

#[test]
fn open_curve_at_boundary() {
    let p = marching_squares(&sample2(square_spec(20), |x, _| x - 0.1), 0.0);
    assert_eq!(p.lines.len(), 1);
    assert_eq!(p.lines[0].len(), 20);
    assert_ne!(p.lines[0].first(), p.lines[0].last());
}
