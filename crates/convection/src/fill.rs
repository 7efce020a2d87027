//! A triangulation of one hole loop through its own vertices whose faces
//! cross neither the faces around the hole nor each other.
//!
//! Ear clipping decides one ear at a time; where every ear of a twisted
//! loop crosses a nearby face (at a cone's sparse tip, on a noisy sheet)
//! it has to take a crossing one. The loop's triangulations are the
//! polygon triangulations of its vertex sequence (a Catalan number of
//! them). The least total area is a dynamic programme over the loop's
//! intervals (Barequet–Sharir, Liepa); it cannot see crossings among the
//! new faces, and testing every candidate face against the faces nearby
//! (exactly) is the cost, so the programme's sub-interval optima serve as
//! lower bounds of a branch-and-bound search over the apexes, which tests
//! only the faces it places: the least-area triangulation crossing
//! nothing.

use surfrecon_geom::intersections::faces_meet;
use surfrecon_geom::DVec3;

/// Faces the search tries before it gives up on a loop (a loop of 24
/// edges has 10^11 triangulations; the bounds leave a handful to try
/// unless faces keep crossing). A loop given up on is opened wider and
/// tried again (`manifold::fill_small_holes`).
const SEARCH_BUDGET: usize = 2_000;

/// What a hole's faces must respect.
pub(crate) struct Surroundings<'a> {
    pub points: &'a [DVec3],
    /// All faces so far; `near` indexes into it.
    pub triangles: &'a [[u32; 3]],
    /// The faces a new face could cross.
    pub near: &'a [u32],
    /// Whether the mesh (or an earlier hole) already has the edge {a, b}.
    pub is_edge: &'a dyn Fn(u32, u32) -> bool,
}

impl Surroundings<'_> {
    fn corners(&self, t: [u32; 3]) -> [DVec3; 3] {
        t.map(|v| self.points[v as usize])
    }

    /// Whether the face `t` meets one of the faces near the hole (beyond
    /// the corners and edge it shares with it; exact).
    pub fn crosses_near(&self, t: [u32; 3]) -> bool {
        let pt = self.corners(t);
        let (lo, hi) = bounds(&pt);
        self.near.iter().any(|&f| {
            let u = self.triangles[f as usize];
            let pu = self.corners(u);
            let (ulo, uhi) = bounds(&pu);
            lo.cmple(uhi).all() && ulo.cmple(hi).all() && faces_meet(t, &pt, u, &pu)
        })
    }

    /// Whether the faces `t` and `u` meet beyond what they share (exact;
    /// apart boxes first, the common case).
    pub fn meet(&self, t: [u32; 3], u: [u32; 3]) -> bool {
        let (pt, pu) = (self.corners(t), self.corners(u));
        let ((lo, hi), (ulo, uhi)) = (bounds(&pt), bounds(&pu));
        lo.cmple(uhi).all() && ulo.cmple(hi).all() && faces_meet(t, &pt, u, &pu)
    }
}

fn bounds(p: &[DVec3; 3]) -> (DVec3, DVec3) {
    (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]))
}

/// The least-area triangulation of the loop `hole` (faces oriented along
/// it) with no face crossing a nearby face or another new face and no
/// diagonal the mesh already has; `None` when there is none (or the
/// search ran out of its budget first).
pub(crate) fn least_area_triangulation(
    hole: &[u32],
    around: &Surroundings,
) -> Option<Vec<[u32; 3]>> {
    let mut search = Search::new(hole, around);
    if !search.lower_bounds[search.interval(0, hole.len() - 1)].is_finite() {
        return None;
    }
    let mut pending = vec![(0, hole.len() - 1)];
    search.branch(&mut pending, 0.0);
    search.best.map(|(_, faces)| faces)
}

/// Branch and bound over the apex of each pending loop interval.
struct Search<'a> {
    hole: &'a [u32],
    around: &'a Surroundings<'a>,
    /// Area of the face (i, k, j) of loop positions, infinite when it
    /// adds an edge the mesh has.
    areas: Vec<f64>,
    /// Whether the face (i, k, j) crosses no nearby face, once asked (the
    /// exact test is the cost: asked only of faces the search places).
    clear: Vec<Option<bool>>,
    /// Least area of the interval i..=j closed by its chord (i, j),
    /// ignoring crossings.
    lower_bounds: Vec<f64>,
    placed: Vec<[u32; 3]>,
    best: Option<(f64, Vec<[u32; 3]>)>,
    tried: usize,
}

impl<'a> Search<'a> {
    fn new(hole: &'a [u32], around: &'a Surroundings<'a>) -> Search<'a> {
        let n = hole.len();
        let mut search = Search {
            hole,
            around,
            areas: vec![f64::INFINITY; n * n * n],
            clear: vec![None; n * n * n],
            lower_bounds: vec![f64::INFINITY; n * n],
            placed: Vec::new(),
            best: None,
            tried: 0,
        };
        search.fill_areas();
        search.fill_lower_bounds();
        search
    }

    fn interval(&self, i: usize, j: usize) -> usize {
        i * self.hole.len() + j
    }

    fn triple(&self, i: usize, k: usize, j: usize) -> usize {
        (i * self.hole.len() + k) * self.hole.len() + j
    }

    fn face(&self, i: usize, k: usize, j: usize) -> [u32; 3] {
        [self.hole[i], self.hole[k], self.hole[j]]
    }

    /// Whether the chord between loop positions i < j may be an edge: a
    /// side of the loop, or a diagonal the mesh does not have yet (else
    /// three faces would share it).
    fn chord_allowed(&self, i: usize, j: usize) -> bool {
        let n = self.hole.len();
        j == i + 1 || (i == 0 && j == n - 1) || !(self.around.is_edge)(self.hole[i], self.hole[j])
    }

    fn fill_areas(&mut self) {
        let n = self.hole.len();
        let points = self.around.points;
        for i in 0..n {
            for k in i + 1..n {
                if !self.chord_allowed(i, k) {
                    continue;
                }
                for j in k + 1..n {
                    if !self.chord_allowed(k, j) || !self.chord_allowed(i, j) {
                        continue;
                    }
                    let [a, b, c] = self.face(i, k, j).map(|v| points[v as usize]);
                    let area = 0.5 * (b - a).cross(c - a).length();
                    let at = self.triple(i, k, j);
                    self.areas[at] = area;
                }
            }
        }
    }

    /// The interval programme, shortest intervals first.
    fn fill_lower_bounds(&mut self) {
        let n = self.hole.len();
        for i in 0..n - 1 {
            let at = self.interval(i, i + 1);
            self.lower_bounds[at] = 0.0;
        }
        for gap in 2..n {
            for i in 0..n - gap {
                let j = i + gap;
                let least = (i + 1..j)
                    .map(|k| self.split_bound(i, k, j))
                    .fold(f64::INFINITY, f64::min);
                let at = self.interval(i, j);
                self.lower_bounds[at] = least;
            }
        }
    }

    /// Least area of the interval i..=j with apex k on its chord.
    fn split_bound(&self, i: usize, k: usize, j: usize) -> f64 {
        self.areas[self.triple(i, k, j)]
            + self.lower_bounds[self.interval(i, k)]
            + self.lower_bounds[self.interval(k, j)]
    }

    fn is_clear(&mut self, i: usize, k: usize, j: usize) -> bool {
        let at = self.triple(i, k, j);
        let face = self.face(i, k, j);
        *self.clear[at].get_or_insert_with(|| !self.around.crosses_near(face))
    }

    fn branch(&mut self, pending: &mut Vec<(usize, usize)>, area: f64) {
        let bound: f64 = area
            + pending
                .iter()
                .map(|&(i, j)| self.lower_bounds[self.interval(i, j)])
                .sum::<f64>();
        let best = self.best.as_ref().map_or(f64::INFINITY, |b| b.0);
        if !bound.is_finite() || bound >= best || self.tried >= SEARCH_BUDGET {
            return;
        }
        let Some((i, j)) = pending.pop() else {
            self.best = Some((area, self.placed.clone()));
            return;
        };
        let mut apexes: Vec<usize> = (i + 1..j)
            .filter(|&k| self.split_bound(i, k, j).is_finite())
            .collect();
        apexes.sort_by(|&k, &m| {
            self.split_bound(i, k, j)
                .total_cmp(&self.split_bound(i, m, j))
        });
        for k in apexes {
            self.tried += 1;
            let t = self.face(i, k, j);
            if !self.is_clear(i, k, j) || self.placed.iter().any(|&u| self.around.meet(t, u)) {
                continue;
            }
            let depth = pending.len();
            pending.extend([(i, k), (k, j)].into_iter().filter(|&(a, b)| b > a + 1));
            self.placed.push(t);
            let face_area = self.areas[self.triple(i, k, j)];
            self.branch(pending, area + face_area);
            self.placed.pop();
            pending.truncate(depth);
        }
        pending.push((i, j));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_edges(_: u32, _: u32) -> bool {
        false
    }

    /// A planar convex loop: the fan or any triangulation has the
    /// polygon's area; the search finds n − 2 faces of that area.
    #[test]
    fn planar_loop_gets_its_area() {
        let n = 9;
        let points: Vec<DVec3> = (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let hole: Vec<u32> = (0..n as u32).collect();
        let around = Surroundings {
            points: &points,
            triangles: &[],
            near: &[],
            is_edge: &no_edges,
        };
        let faces = least_area_triangulation(&hole, &around).unwrap();
        assert_eq!(faces.len(), n - 2);
        let area: f64 = faces
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| points[v as usize]);
                0.5 * (b - a).cross(c - a).z
            })
            .sum();
        let polygon = 0.5 * n as f64 * (std::f64::consts::TAU / n as f64).sin();
        assert!((area - polygon).abs() < 1e-12, "{area} vs {polygon}");
    }

    /// A square loop pierced through its middle by a standing face: every
    /// triangulation of the square covers its middle, so none is clear.
    #[test]
    fn pierced_loop_has_no_clear_triangulation() {
        let points: Vec<DVec3> = [
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
            [0.1, 0.1, -1.0],
            [-0.1, -0.1, -1.0],
            [0.0, 0.0, 1.0],
        ]
        .map(DVec3::from_array)
        .to_vec();
        let standing = [[4, 5, 6]];
        let around = Surroundings {
            points: &points,
            triangles: &standing,
            near: &[0],
            is_edge: &no_edges,
        };
        assert!(least_area_triangulation(&[0, 1, 2, 3], &around).is_none());
        // Without the standing face either diagonal will do.
        let open = Surroundings {
            near: &[],
            ..around
        };
        let faces = least_area_triangulation(&[0, 1, 2, 3], &open).unwrap();
        assert_eq!(faces.len(), 2);
    }
}
