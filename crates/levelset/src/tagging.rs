//! Initial surface: outer distance contour, then the fast tagging algorithm.
//!
//! 1. Exterior = nodes connected to the grid border through nodes with
//!    d > ε (flood fill), optionally plus everything outside a box.
//! 2. Fast tagging (Zhao, Osher, Fedkiw §5.2): interior nodes next to the
//!    exterior are temporary boundary nodes in a max-heap on d. Pop the
//!    largest; if it has an interior neighbour with d ≥ its own it becomes a
//!    final boundary node, else it turns exterior and its interior
//!    neighbours enter the heap. Stop when the largest d in the heap is
//!    below the tolerance; the rest become final boundary nodes.
//!
//! 3. Optionally (the default in the pipeline) tagging keeps the topology
//!    of the outer contour: a node is only turned exterior if it is a
//!    simple point, so the exterior cannot tunnel through a hole in the
//!    data that ε closed. Afterwards [`remove_unsupported`] drops separate
//!    inside pieces that hold (almost) no data.
//!
//! The result is the inside/outside labelling whose interface is the
//! initial surface: roughly a polyhedron with vertices on the data.

use std::collections::BinaryHeap;
use surfrecon_grid::topology::Neighbourhood;
use surfrecon_grid::Field;

/// Label of a node during tagging.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Tag {
    Exterior,
    Interior,
    /// In the heap: interior node next to the exterior.
    Temporary,
    /// Boundary node that stays inside.
    Boundary,
}

/// What the tagging produced.
#[derive(Clone, Debug)]
pub struct Tagging {
    /// One tag per node; inside = anything but [`Tag::Exterior`].
    pub tags: Vec<Tag>,
    /// The ε of the outer contour actually used.
    pub epsilon: f64,
    /// Nodes popped from the heap.
    pub heap_pops: usize,
}

impl Tagging {
    /// Inside/outside labels (`true` = inside).
    pub fn inside(&self) -> Vec<bool> {
        self.tags.iter().map(|&t| t != Tag::Exterior).collect()
    }

    /// Number of inside nodes.
    pub fn inside_count(&self) -> usize {
        self.tags.iter().filter(|&&t| t != Tag::Exterior).count()
    }
}

/// A box (in world coordinates) outside of which every node is exterior.
pub type BoundingBox<const D: usize> = ([f64; D], [f64; D]);

/// Exterior flood fill of the outer contour d = `epsilon`: nodes reachable
/// from the grid border through nodes with d > ε, plus every node outside
/// `bbox`. Returns the tags (exterior or interior) and the interior nodes
/// next to the exterior, the seeds of the tagging heap.
pub fn outer_contour<const D: usize>(
    d: &Field<D>,
    epsilon: f64,
    bbox: Option<&BoundingBox<D>>,
) -> (Vec<Tag>, Vec<u32>) {
    let spec = d.spec;
    let strides = spec.strides();
    let mut tags = vec![Tag::Interior; spec.node_count()];
    let mut queue: Vec<u32> = Vec::new();
    for (l, tag) in tags.iter_mut().enumerate() {
        let idx = spec.unlinear(l);
        let on_border = (0..D).any(|a| idx[a] == 0 || idx[a] + 1 == spec.dims[a]);
        let outside_box = bbox.is_some_and(|(lo, hi)| {
            let p = spec.position(idx);
            (0..D).any(|a| p[a] < lo[a] || p[a] > hi[a])
        });
        if on_border || outside_box {
            *tag = Tag::Exterior;
            queue.push(l as u32);
        }
    }
    let mut front = Vec::new();
    let mut head = 0;
    while head < queue.len() {
        let l = queue[head] as usize;
        head += 1;
        let idx = spec.unlinear(l);
        for a in 0..D {
            let mut visit = |n: usize| {
                if tags[n] != Tag::Interior {
                    return;
                }
                if d.values[n] > epsilon {
                    tags[n] = Tag::Exterior;
                    queue.push(n as u32);
                } else {
                    tags[n] = Tag::Temporary;
                    front.push(n as u32);
                }
            };
            if idx[a] > 0 {
                visit(l - strides[a]);
            }
            if idx[a] + 1 < spec.dims[a] {
                visit(l + strides[a]);
            }
        }
    }
    (tags, front)
}

/// Number of interior nodes with d > ε: positive when the outer contour
/// encloses a cavity, i.e. ε closed every gap of the data.
pub fn enclosed_count<const D: usize>(d: &Field<D>, tags: &[Tag], epsilon: f64) -> usize {
    tags.iter()
        .zip(&d.values)
        .filter(|(&t, &v)| t == Tag::Interior && v > epsilon)
        .count()
}

/// Heap key: d ≥ 0, so its bit pattern orders like the number; ties are
/// broken by node index to keep the result deterministic.
fn key(d: f64, l: usize) -> (u64, u32) {
    (d.max(0.0).to_bits(), l as u32)
}

/// Node labels the fast tagging reads and writes, by linear node index.
pub trait TagStore {
    fn tag(&self, n: usize) -> Tag;
    fn set_tag(&mut self, n: usize, t: Tag);
}

impl TagStore for [Tag] {
    fn tag(&self, n: usize) -> Tag {
        self[n]
    }
    fn set_tag(&mut self, n: usize, t: Tag) {
        self[n] = t;
    }
}

/// The fast tagging algorithm on `tags` (from [`outer_contour`]; the seeds
/// in `front` must be tagged [`Tag::Temporary`]). With `keep_topology`, a
/// node whose removal would change the topology of the inside (a simple
/// point test on its 3^D neighbourhood) stays a final boundary node, so the
/// exterior cannot tunnel through gaps in the data that the outer contour
/// closed. Returns the heap pops.
pub fn fast_tag<const D: usize>(
    d: &Field<D>,
    tags: &mut [Tag],
    front: &[u32],
    tolerance: f64,
    keep_topology: bool,
) -> usize {
    let strides = d.spec.strides();
    fast_tag_with(
        &strides,
        |n| d.values[n],
        tags,
        front,
        tolerance,
        keep_topology,
    )
}

/// [`fast_tag`] on any store of tags over a grid with `strides`, reading d
/// by `d` (only at interior and temporary nodes, which must not touch the
/// grid border).
pub fn fast_tag_with<const D: usize, S: TagStore + ?Sized>(
    strides: &[usize; D],
    d: impl Fn(usize) -> f64,
    tags: &mut S,
    front: &[u32],
    tolerance: f64,
    keep_topology: bool,
) -> usize {
    let cube = Neighbourhood::new(strides);
    let mut heap: BinaryHeap<(u64, u32)> = front
        .iter()
        .map(|&l| key(d(l as usize), l as usize))
        .collect();
    let mut pops = 0;
    while let Some(&(bits, l)) = heap.peek() {
        let dist = f64::from_bits(bits);
        if dist < tolerance {
            break;
        }
        heap.pop();
        pops += 1;
        let l = l as usize;
        // Interior nodes never touch the grid border (the border is
        // exterior), so their neighbours are all in range.
        let neighbours = || strides.iter().flat_map(move |&s| [l - s, l + s]);
        let blocked = neighbours().any(|n| tags.tag(n) == Tag::Interior && d(n) >= dist)
            || (keep_topology && !cube.is_simple(l, |n| tags.tag(n) != Tag::Exterior));
        if blocked {
            tags.set_tag(l, Tag::Boundary);
            continue;
        }
        tags.set_tag(l, Tag::Exterior);
        for n in neighbours() {
            if tags.tag(n) == Tag::Interior {
                tags.set_tag(n, Tag::Temporary);
                heap.push(key(d(n), n));
            }
        }
    }
    // What is left in the heap is exactly the temporary nodes.
    for (_, l) in heap {
        tags.set_tag(l as usize, Tag::Boundary);
    }
    pops
}

/// Outer contour then fast tagging. With `grow_epsilon`, ε is also tried
/// larger (×1.5 per try, up to half the grid extent) and the ε whose
/// contour encloses the largest cavity (interior nodes with d > ε) wins:
/// for well-sampled closed data that is the smallest ε (the cavity only
/// shrinks as ε grows), while gaps (holes in a scan, sparse curves) leak
/// the exterior into the inside until an ε large enough closes them, when
/// the cavity jumps up. Past half the grid extent the grid border itself
/// (the bounding box) is the start.
pub fn tag<const D: usize>(
    d: &Field<D>,
    epsilon: f64,
    grow_epsilon: bool,
    tolerance: f64,
    bbox: Option<&BoundingBox<D>>,
    keep_topology: bool,
) -> Tagging {
    let spec = d.spec;
    let largest = (0..D)
        .map(|a| (spec.dims[a] - 1) as f64 * spec.spacing)
        .fold(0.0, f64::max);
    let mut eps = epsilon;
    let (mut tags, mut front) = outer_contour(d, eps, bbox);
    if grow_epsilon {
        let mut best = enclosed_count(d, &tags, eps);
        let substantial = (spec.node_count() / 1000).max(1);
        let mut trial = eps;
        loop {
            trial *= 1.5;
            if trial >= 0.5 * largest {
                break;
            }
            let (t, f) = outer_contour(d, trial, bbox);
            let cavity = enclosed_count(d, &t, trial);
            if cavity > best {
                (best, eps, tags, front) = (cavity, trial, t, f);
            } else if best >= substantial && cavity < best / 4 {
                // Past a real peak: larger ε only shrinks the cavity further.
                break;
            }
        }
    }
    let heap_pops = fast_tag(d, &mut tags, &front, tolerance, keep_topology);
    Tagging {
        tags,
        epsilon: eps,
        heap_pops,
    }
}

/// Data items a separate inside component needs to be kept.
pub const MIN_SUPPORT: usize = 10;

/// Removes (turns exterior) every face-connected inside component that
/// holds fewer than [`MIN_SUPPORT`] of the `data_nodes` (the node nearest to
/// each datum), except the best supported one: isolated data far from the
/// bulk (outliers the cleaning kept) must not become surfaces of their own.
/// Returns the number of components removed.
pub fn remove_unsupported<const D: usize>(
    spec: &surfrecon_grid::GridSpec<D>,
    inside: &mut [bool],
    data_nodes: &[usize],
) -> usize {
    let strides = spec.strides();
    let mut component = vec![u32::MAX; inside.len()];
    let mut sizes: Vec<usize> = Vec::new();
    let mut stack = Vec::new();
    for start in 0..inside.len() {
        if !inside[start] || component[start] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        sizes.push(0);
        component[start] = id;
        stack.push(start);
        while let Some(l) = stack.pop() {
            let idx = spec.unlinear(l);
            for a in 0..D {
                let below = (idx[a] > 0).then(|| l - strides[a]);
                let above = (idx[a] + 1 < spec.dims[a]).then(|| l + strides[a]);
                for n in [below, above].into_iter().flatten() {
                    if inside[n] && component[n] == u32::MAX {
                        component[n] = id;
                        stack.push(n);
                    }
                }
            }
        }
    }
    if sizes.len() < 2 {
        return 0;
    }
    for &l in data_nodes {
        if let Some(&c) = component.get(l).filter(|&&c| c != u32::MAX) {
            sizes[c as usize] += 1;
        }
    }
    let best = (0..sizes.len()).max_by_key(|&c| (sizes[c], std::cmp::Reverse(c)));
    let doomed: Vec<bool> = (0..sizes.len())
        .map(|c| Some(c) != best && sizes[c] < MIN_SUPPORT)
        .collect();
    for (l, c) in component.iter().enumerate() {
        if *c != u32::MAX && doomed[*c as usize] {
            inside[l] = false;
        }
    }
    doomed.iter().filter(|&&x| x).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_grid::GridSpec;

    /// Distance to a set of 2D points, brute force.
    fn point_distance(spec: GridSpec<2>, pts: &[[f64; 2]]) -> Field<2> {
        let values = (0..spec.node_count())
            .map(|l| {
                let [x, y] = spec.position(spec.unlinear(l));
                pts.iter()
                    .map(|p| ((x - p[0]).powi(2) + (y - p[1]).powi(2)).sqrt())
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        Field { spec, values }
    }

    fn grid() -> GridSpec<2> {
        GridSpec {
            origin: [-2.0, -2.0],
            spacing: 0.05,
            dims: [81, 81],
        }
    }

    fn circle_points(n: usize, r: f64) -> Vec<[f64; 2]> {
        (0..n)
            .map(|i| {
                let t = i as f64 / n as f64 * std::f64::consts::TAU;
                [r * t.cos(), r * t.sin()]
            })
            .collect()
    }

    #[test]
    fn circle_is_tagged_close_to_the_data() {
        let spec = grid();
        let d = point_distance(spec, &circle_points(60, 1.0));
        let t = tag(&d, 0.15, false, spec.spacing, None, false);
        let inside = t.inside();
        for (l, &is_inside) in inside.iter().enumerate() {
            let [x, y] = spec.position(spec.unlinear(l));
            let r = (x * x + y * y).sqrt();
            if r < 0.85 {
                assert!(is_inside, "node at r={r} should be inside");
            }
            if r > 1.1 {
                assert!(!is_inside, "node at r={r} should be outside");
            }
        }
        assert!(t.heap_pops > 0);
    }

    #[test]
    fn tagging_moves_into_a_concavity_the_contour_misses() {
        // A "C" shape: points on a circle with a notch pushed inwards.
        let spec = grid();
        let mut pts = circle_points(80, 1.2);
        pts.extend((0..20).map(|i| [0.3 + i as f64 * 0.045, 0.0]));
        let d = point_distance(spec, &pts);
        let t = tag(&d, 0.6, false, spec.spacing, None, false);
        // With ε = 0.6 the contour alone keeps (1.0, 0.6) inside; tagging
        // must still leave it inside (inside the circle) but the node far
        // outside the circle is exterior.
        let node = |x: f64, y: f64| {
            spec.linear([((x + 2.0) / 0.05) as usize, ((y + 2.0) / 0.05) as usize])
        };
        assert!(t.tags[node(-0.5, 0.0)] != Tag::Exterior);
        assert!(t.tags[node(1.7, 1.7)] == Tag::Exterior);
    }

    #[test]
    fn epsilon_grows_until_sparse_data_enclose_a_cavity() {
        let spec = grid();
        // 8 points on a circle of radius 1: gaps of 0.77 need ε ≳ 0.4.
        let d = point_distance(spec, &circle_points(8, 1.0));
        let t = tag(&d, 0.1, true, spec.spacing, None, false);
        assert!(t.epsilon > 0.35, "ε = {}", t.epsilon);
        let centre = spec.linear([40, 40]);
        assert!(t.tags[centre] != Tag::Exterior);
    }

    #[test]
    fn components_without_data_support_are_removed() {
        let spec = grid();
        let mut pts = circle_points(60, 1.0);
        // A lone outlier far outside the circle, beyond ε of it.
        pts.push([1.7, 1.7]);
        let d = point_distance(spec, &pts);
        let t = tag(&d, 0.15, false, spec.spacing, None, true);
        let mut inside = t.inside();
        let node = |p: &[f64; 2]| {
            let g = spec.to_grid(*p);
            spec.linear([g[0].round() as usize, g[1].round() as usize])
        };
        let lone = node(&[1.7, 1.7]);
        assert!(inside[lone], "the outlier's own node survives tagging");
        let data: Vec<usize> = pts.iter().map(node).collect();
        assert_eq!(remove_unsupported(&spec, &mut inside, &data), 1);
        assert!(!inside[lone]);
        assert!(inside[spec.linear([40, 40])], "the circle stays");
    }
}
