//! Training data: the oriented surface samples, box subdivision into base
//! points, and off-surface points along the normals.
//!
//! Surface points get target 0. Off-surface points x ± y·n get target ±y
//! (positive outside, negative inside), kept only if no surface point lies
//! closer than 0.9·y: otherwise the surface bends back and ±y would not be
//! within 10% of the true signed distance.

use crate::error::{Result, SvmError};
use glam::DVec3;
use rayon::prelude::*;
use surfrecon_geom::spatial::{KdTree, Neighbour};
use surfrecon_geom::Aabb;

/// A position with the value f should take there, and the weight of its
/// loss term (1 for a base point standing for a typical number of samples).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrainingPoint {
    pub position: DVec3,
    pub target: f64,
    pub weight: f64,
}

/// How often an off-surface point's distance is halved to pass the
/// consistency check before it is left out.
const OFFSET_HALVINGS: u32 = 3;
/// Nearest an off-surface point moves to its sample, in noise σ.
const NOISE_OFFSET_FLOOR: f64 = 3.0;

/// Validated oriented surface samples with a spatial index.
pub struct SurfaceSamples {
    pub points: Vec<DVec3>,
    /// Unit outward normals, one per point.
    pub normals: Vec<DVec3>,
    pub tree: KdTree,
    pub bounds: Aabb,
    /// Bounding-box diagonal (the "diameter" every relative size refers to).
    pub diameter: f64,
    /// Median distance from a sample to its nearest other sample.
    pub spacing: f64,
    /// Per sample: distance to its [`LOCAL_NEIGHBOURS`]-th nearest other
    /// sample (how isolated it is).
    pub reach: Vec<f64>,
    /// Median of `reach`.
    pub typical_reach: f64,
    /// When set, the samples the off-surface consistency check looks at
    /// (all samples otherwise) with their indices in `points`: see
    /// [`Self::exclude_from_consistency`].
    consistency_tree: Option<(KdTree, Vec<usize>)>,
    /// Noise σ the consistency check allows for (see [`Self::set_noise`]).
    noise: f64,
    /// Per sample: its normal agrees with the mean normal of its
    /// [`LOCAL_NEIGHBOURS`] nearest other samples (cosine ≥
    /// [`MIN_NORMAL_AGREEMENT`]). A stray point with an arbitrary normal
    /// next to a surface fails this, and its off-surface points, which
    /// would claim the wrong side, are not used.
    pub normal_agrees: Vec<bool>,
}

/// Scatter of noisy samples about the surface, in noise σ.
const NOISE_SCATTER: f64 = 2.0;

/// Neighbours searched for the other side of a thin part (see
/// [`SurfaceSamples::backs_onto_other_side`]): on a plate a couple of
/// spacings thick, about half of them lie across it.
pub const THIN_NEIGHBOURS: usize = 32;

/// Neighbours that define a sample's local reach and normal agreement.
pub const LOCAL_NEIGHBOURS: usize = 6;

/// Of a sample's [`LOCAL_NEIGHBOURS`] nearest, how many must lie on its
/// tangent disc (see [`SurfaceSamples::spans_tangent_disc`]): half.
pub const TANGENT_NEIGHBOURS: usize = 3;
/// Largest |cosine| between a sample's normal and the direction to a
/// neighbour on its tangent disc (about 17° out of the plane): room for
/// curvature over a few spacings, none for a surface passing below.
pub const TANGENT_ELEVATION: f64 = 0.3;
/// Nearest, in noise σ, that a neighbour on a sample's tangent disc lies:
/// closer, the noise alone tilts the direction to it by more than
/// [`TANGENT_ELEVATION`], so noisy samples would pass or fail by chance
/// (harness spikes, 1% noise, chaining every sparse-enough sample on its
/// tangent disc: noisy samples around the spike tips passed at the coarse
/// levels and gave two handles).
pub const TANGENT_NOISE_SPAN: f64 = 10.0;
/// Least cosine between the normals of a sample and of a neighbour on its
/// tangent disc (about 45°).
pub const TANGENT_NORMAL_AGREEMENT: f64 = 0.7;

/// Lowest cosine between a sample's normal and its neighbours' mean normal
/// that counts as agreement; a cube corner's normal still agrees (its
/// neighbours' mean lies at 55° from each face normal, cosine 0.58).
pub const MIN_NORMAL_AGREEMENT: f64 = 0.3;

impl SurfaceSamples {
    /// Check and index `points` with `normals` (normalized here); rejects
    /// empty or mismatched input, non-finite values and zero normals.
    pub fn new(points: &[DVec3], normals: &[DVec3]) -> Result<SurfaceSamples> {
        if points.len() < 4 {
            return Err(SvmError::InvalidInput(format!(
                "need at least 4 surface points to fit, got {}",
                points.len()
            )));
        }
        if normals.len() != points.len() {
            return Err(SvmError::InvalidInput(format!(
                "{} points but {} normals",
                points.len(),
                normals.len()
            )));
        }
        if let Some(i) = points.iter().position(|p| !p.is_finite()) {
            return Err(SvmError::InvalidInput(format!(
                "point {i} has a non-finite coordinate"
            )));
        }
        let normals = unit_normals(normals)?;
        let bounds = Aabb::from_points(points);
        let diameter = bounds.diagonal();
        if diameter.is_nan() || diameter <= 0.0 {
            return Err(SvmError::InvalidInput(
                "all points coincide: the input has no extent".into(),
            ));
        }
        let tree = KdTree::new(points);
        let spacing = median_spacing(points, &tree).max(diameter * 1e-9);
        let (reach, normal_agrees) = local_reach_and_agreement(points, &normals, &tree);
        let typical_reach = median(&reach);
        Ok(SurfaceSamples {
            points: points.to_vec(),
            normals,
            tree,
            bounds,
            diameter,
            spacing,
            reach,
            typical_reach,
            normal_agrees,
            consistency_tree: None,
            noise: 0.0,
        })
    }

    /// Off-surface points at distance `y` on both sides of each sample in
    /// `reps`, interleaved (+ then −) in the order of `reps`, each passing
    /// the 0.9·y consistency check; all of weight 1.
    pub fn off_surface(&self, reps: &[usize], y: f64) -> Vec<TrainingPoint> {
        let weighted: Vec<(usize, f64)> = reps.iter().map(|&i| (i, 1.0)).collect();
        self.off_surface_weighted(&weighted, y)
    }

    /// [`Self::off_surface`] for (sample, weight) pairs; each off-surface
    /// point inherits its sample's weight.
    pub fn off_surface_weighted(&self, reps: &[(usize, f64)], y: f64) -> Vec<TrainingPoint> {
        reps.par_iter()
            .flat_map_iter(|&(i, weight)| self.off_surface_of(i, y, weight))
            .collect()
    }

    /// The off-surface points of sample `i` at distance `y` or less (+ then −)
    /// that pass the consistency check, with weight `weight`; none when
    /// the sample's normal disagrees with its neighbours'.
    pub fn off_surface_of(
        &self,
        i: usize,
        y: f64,
        weight: f64,
    ) -> impl Iterator<Item = TrainingPoint> + '_ {
        let signs: &[f64] = if self.normal_agrees[i] {
            &[1.0, -1.0]
        } else {
            &[]
        };
        // Where the other side of a thin part is nearer than y, the point
        // moves closer, down to y / 4 but not into the noise: without it a
        // part thinner than the level's offset has no inside at all. A
        // sheet facing the same way (two misregistered scans of one
        // surface) is no thin part: a point between the sheets would claim
        // the wrong side of one of them and pit the surface.
        let least = (NOISE_OFFSET_FLOOR * self.noise).min(y);
        signs.iter().filter_map(move |&sign| {
            for k in 0..OFFSET_HALVINGS {
                let d = y / f64::from(1u32 << k);
                if d < least {
                    return None;
                }
                let position = self.points[i] + self.normals[i] * (sign * d);
                match self.blocking_sample(position, d) {
                    None => {
                        return Some(TrainingPoint {
                            position,
                            target: sign * d,
                            weight,
                        })
                    }
                    Some(b) if self.normals[b].dot(self.normals[i]) > 0.0 => return None,
                    Some(_) => {}
                }
            }
            None
        })
    }

    /// Flip the normals of samples `flips` (see
    /// [`crate::multiscale::FitReport::normals_flipped`]) and recompute
    /// which normals agree with their neighbours'.
    pub fn flip_normals(&mut self, flips: &[usize]) {
        for &i in flips {
            self.normals[i] = -self.normals[i];
        }
        // A flip changes the agreement of the samples that have the flipped
        // one among their nearest: those near it.
        let mut touched: Vec<usize> = flips
            .par_iter()
            .flat_map_iter(|&i| self.tree.knn(self.points[i], 2 * LOCAL_NEIGHBOURS + 1))
            .map(|n| n.index)
            .collect();
        touched.par_sort_unstable();
        touched.dedup();
        let agrees: Vec<bool> = touched
            .par_iter()
            .map(|&i| {
                let near = self.tree.knn(self.points[i], LOCAL_NEIGHBOURS + 1);
                agrees_with(i, &near, &self.normals)
            })
            .collect();
        for (i, a) in touched.into_iter().zip(agrees) {
            self.normal_agrees[i] = a;
        }
    }

    /// Whether sample `i` backs onto the other side of a part thinner
    /// than `within`: one of its [`THIN_NEIGHBOURS`] nearest samples lies
    /// behind it (more along its normal than beside it, at most `within`
    /// away) and faces the other way. Such a pair is consistent as it is,
    /// and a level wider than the part only sees a blob there, whose
    /// gradient says nothing about which way each side faces.
    pub fn backs_onto_other_side(&self, i: usize, within: f64) -> bool {
        let (p, n) = (self.points[i], self.normals[i]);
        self.tree
            .knn(p, THIN_NEIGHBOURS + 1)
            .into_iter()
            .filter(|m| m.index != i && m.distance <= within)
            .any(|m| {
                let d = self.points[m.index] - p;
                let behind = -d.dot(n);
                let beside = (d + behind * n).length();
                behind > beside && self.normals[m.index].dot(n) < -0.5
            })
    }

    /// Whether sample `i` lies on a surface sampled around it, however
    /// sparsely: at least [`TANGENT_NEIGHBOURS`] of its
    /// [`LOCAL_NEIGHBOURS`] nearest other samples, at least
    /// [`TANGENT_NOISE_SPAN`] noise σ away, either lie along its tangent
    /// plane (their direction within [`TANGENT_ELEVATION`] of it) and face
    /// its way (normal cosine ≥ [`TANGENT_NORMAL_AGREEMENT`]), or have it
    /// on theirs (the same angle) and a normal that agrees with their own
    /// neighbours'. The second holds across an edge or corner next to the
    /// sample, where most neighbours lie on the other faces (harness box,
    /// non-uniform: the samples of the sparse corner failed the first
    /// alone and were left out, denting the corner 0.024 deep). This does
    /// not depend on how far apart they are, so a sparsely but evenly
    /// sampled face passes as a dense one does; a stray sample's
    /// neighbours are a surface it floats beside (below or above its
    /// tangent plane unless its normal is turned away from theirs, and it
    /// above theirs) or other stray samples in random directions with
    /// random normals, which disagree with their own neighbours'.
    pub fn spans_tangent_disc(&self, i: usize) -> bool {
        let (p, n) = (self.points[i], self.normals[i]);
        let nearest = TANGENT_NOISE_SPAN * self.noise;
        let along = self
            .tree
            .knn(p, LOCAL_NEIGHBOURS + 1)
            .into_iter()
            .filter(|m| m.index != i && m.distance >= nearest)
            .filter(|m| {
                let q = m.index;
                let direction = (self.points[q] - p).normalize_or_zero();
                let on_mine = direction.dot(n).abs() <= TANGENT_ELEVATION
                    && self.normals[q].dot(n) >= TANGENT_NORMAL_AGREEMENT;
                let on_theirs = self.normal_agrees[q]
                    && direction.dot(self.normals[q]).abs() <= TANGENT_ELEVATION;
                on_mine || on_theirs
            })
            .count();
        along >= TANGENT_NEIGHBOURS
    }

    /// Indices of the samples that are not isolated: whose [`Self::reach`]
    /// is at most `ratio` times its median over all samples.
    pub fn unisolated(&self, ratio: f64) -> Vec<usize> {
        let all = 0..self.points.len();
        if ratio.is_infinite() {
            return all.collect();
        }
        all.filter(|&i| self.reach[i] <= ratio * self.typical_reach)
            .collect()
    }

    /// A sample that makes a good box representative: about as close to
    /// its neighbours as typical (not a stray point in a gap between
    /// sheets, where a box's mean often falls) and with an agreeing normal.
    pub fn is_typical(&self, i: usize) -> bool {
        self.normal_agrees[i] && self.reach[i] <= 2.0 * self.typical_reach
    }

    /// Let the off-surface consistency check look only at the samples in
    /// `kept`: stray samples left out of the fit must not veto off-surface
    /// points of the real surface either.
    pub fn exclude_from_consistency(&mut self, kept: &[usize]) {
        if kept.len() == self.points.len() {
            self.consistency_tree = None;
        } else {
            let points: Vec<DVec3> = kept.iter().map(|&i| self.points[i]).collect();
            self.consistency_tree = Some((KdTree::new(&points), kept.to_vec()));
        }
    }

    /// Declare the samples' noise σ (0 by default): noisy samples scatter
    /// about 2σ either side of the surface, so the consistency check
    /// allows that much on top of its 10% (otherwise it would reject most
    /// off-surface points of a noisy scan and leave f undetermined).
    pub fn set_noise(&mut self, sigma: f64) {
        self.noise = sigma.max(0.0);
    }

    /// The noise σ declared with [`Self::set_noise`].
    pub fn noise(&self) -> f64 {
        self.noise
    }

    /// The sample (index into `points`) nearest to `position` when it is
    /// closer than 0.9·y (less the noise scatter, but never under half of
    /// y): an off-surface point there would claim that sample's side.
    fn blocking_sample(&self, position: DVec3, y: f64) -> Option<usize> {
        let least = (0.9 * y - NOISE_SCATTER * self.noise).max(0.5 * y);
        let nearest = match &self.consistency_tree {
            Some((tree, kept)) => tree.nearest(position).map(|n| (kept[n.index], n.distance)),
            None => self.tree.nearest(position).map(|n| (n.index, n.distance)),
        };
        nearest.and_then(|(i, distance)| (distance < least).then_some(i))
    }
}

fn unit_normals(normals: &[DVec3]) -> Result<Vec<DVec3>> {
    normals
        .iter()
        .enumerate()
        .map(|(i, n)| {
            let len = n.length();
            if len.is_finite() && len > 0.0 {
                Ok(*n / len)
            } else {
                Err(SvmError::InvalidInput(format!(
                    "normal {i} is zero or not finite: {n}"
                )))
            }
        })
        .collect()
}

/// Per sample: the distance to its [`LOCAL_NEIGHBOURS`]-th nearest other
/// sample, and whether its normal agrees with theirs.
fn local_reach_and_agreement(
    points: &[DVec3],
    normals: &[DVec3],
    tree: &KdTree,
) -> (Vec<f64>, Vec<bool>) {
    (0..points.len())
        .into_par_iter()
        .map(|i| {
            let near = tree.knn(points[i], LOCAL_NEIGHBOURS + 1);
            let reach = near.last().map_or(f64::INFINITY, |n| n.distance);
            (reach, agrees_with(i, &near, normals))
        })
        .unzip()
}

/// Whether sample `i`'s normal agrees with the mean normal of the other
/// samples in `near`.
fn agrees_with(i: usize, near: &[Neighbour], normals: &[DVec3]) -> bool {
    let mean: DVec3 = near
        .iter()
        .filter(|n| n.index != i)
        .map(|n| normals[n.index])
        .sum();
    mean.try_normalize()
        .is_none_or(|m| m.dot(normals[i]) >= MIN_NORMAL_AGREEMENT)
}

fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut sorted = values.to_vec();
    let mid = sorted.len() / 2;
    *sorted.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Median nearest-neighbour distance over an evenly strided subset.
fn median_spacing(points: &[DVec3], tree: &KdTree) -> f64 {
    let stride = (points.len() / 2000).max(1);
    let mut d: Vec<f64> = (0..points.len())
        .step_by(stride)
        .filter_map(|i| {
            tree.knn(points[i], 2)
                .into_iter()
                .map(|n| n.distance)
                .find(|&d| d > 0.0)
        })
        .collect();
    if d.is_empty() {
        return 0.0;
    }
    d.sort_unstable_by(f64::total_cmp);
    d[d.len() / 2]
}

/// Box subdivision: cubes of side `h` from `origin`; one representative per
/// occupied cube, the point nearest the mean of the cube's points (so a
/// stray point sharing a cube with the surface is not chosen), with the
/// number of points in its cube. Returned in Morton order of the cubes,
/// which keeps neighbours close in memory.
pub fn box_representatives(points: &[DVec3], origin: DVec3, h: f64) -> Vec<(usize, usize)> {
    box_representatives_preferring(points, |_| true, origin, h)
}

/// [`box_representatives`] choosing among the cube's points for which
/// `preferred` holds, when it has any (the count covers all its points).
pub fn box_representatives_preferring(
    points: &[DVec3],
    preferred: impl Fn(usize) -> bool + Sync,
    origin: DVec3,
    h: f64,
) -> Vec<(usize, usize)> {
    let mut keyed: Vec<(u64, u32)> = points
        .par_iter()
        .enumerate()
        .map(|(i, p)| (morton_key(*p, origin, h), i as u32))
        .collect();
    keyed.par_sort_unstable();
    let groups: Vec<&[(u64, u32)]> = keyed.chunk_by(|a, b| a.0 == b.0).collect();
    groups
        .par_iter()
        .map(|g| (representative(points, g, &preferred), g.len()))
        .collect()
}

fn representative(
    points: &[DVec3],
    group: &[(u64, u32)],
    preferred: &impl Fn(usize) -> bool,
) -> usize {
    let mean = group
        .iter()
        .map(|&(_, i)| points[i as usize])
        .sum::<DVec3>()
        / group.len() as f64;
    let members = || group.iter().map(|&(_, i)| i as usize);
    let any_preferred = members().any(preferred);
    members()
        .filter(|&i| !any_preferred || preferred(i))
        .min_by(|&a, &b| {
            points[a]
                .distance_squared(mean)
                .total_cmp(&points[b].distance_squared(mean))
        })
        .expect("groups are non-empty")
}

/// Interleaved bits of the cube coordinates (21 bits per axis).
fn morton_key(p: DVec3, origin: DVec3, h: f64) -> u64 {
    let c = ((p - origin) / h).floor();
    let clamp = |v: f64| v.clamp(0.0, ((1u64 << 21) - 1) as f64) as u64;
    spread(clamp(c.x)) | (spread(clamp(c.y)) << 1) | (spread(clamp(c.z)) << 2)
}

/// Spread the low 21 bits of `v` to every third bit.
fn spread(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | (x << 32)) & 0x1f00000000ffff;
    x = (x | (x << 16)) & 0x1f0000ff0000ff;
    x = (x | (x << 8)) & 0x100f00f00f00f00f;
    x = (x | (x << 4)) & 0x10c30c30c30c30c3;
    x = (x | (x << 2)) & 0x1249249249249249;
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use surfrecon_geom::shapes::{icosphere, sample_surface, torus};

    #[test]
    fn a_second_sheet_facing_the_same_way_keeps_points_out_between() {
        // Two parallel sheets 0.2 apart, both facing +z (two misregistered
        // scans of one surface): an offset of 0.3 from the lower sheet lands
        // next to the upper one; moving it closer (to 0.075) would put an
        // "outside" point between the two sheets, so there is none.
        let grid = |z: f64| {
            (0..400).map(move |i| DVec3::new((i % 20) as f64 * 0.05, (i / 20) as f64 * 0.05, z))
        };
        let points: Vec<DVec3> = grid(0.0).chain(grid(0.2)).collect();
        let normals = vec![DVec3::Z; points.len()];
        let s = SurfaceSamples::new(&points, &normals).unwrap();
        let lower: Vec<usize> = (0..400).collect();
        let outside = s
            .off_surface(&lower, 0.3)
            .into_iter()
            .filter(|p| p.target > 0.0);
        assert!(outside
            .into_iter()
            .all(|p| p.target == 0.3 || p.position.z > 0.1));
    }

    #[test]
    fn off_surface_points_pass_the_consistency_check() {
        let pc = sample_surface(&torus(1.0, 0.25, 64, 32), 3000, 1);
        let s = SurfaceSamples::new(&pc.positions, pc.normals.as_ref().unwrap()).unwrap();
        let reps: Vec<usize> = (0..pc.len()).collect();
        // Inside the tube (radius 0.25) an offset of 0.3 would cross to the
        // far wall: inner points move in to 0.15, outer ones stay at 0.3.
        let pts = s.off_surface(&reps, 0.3);
        assert!(pts.iter().all(|p| p.target == 0.3 || p.target == -0.15));
        let inner = pts.iter().filter(|p| p.target < 0.0).count();
        assert!(
            inner > 1000 && pts.len() - inner > 1000,
            "{inner} of {}",
            pts.len()
        );
        for p in &pts {
            let nearest = s.tree.nearest(p.position).unwrap().distance;
            assert!(nearest >= 0.9 * p.target.abs(), "{p:?} {nearest}");
        }
        let small = s.off_surface(&reps, 0.05);
        let inside = small.iter().filter(|p| p.target < 0.0).count();
        assert!(inside > 2500, "inside {inside}");
    }

    #[test]
    fn declared_noise_keeps_off_surface_points_of_a_noisy_plane() {
        // A plane z = 0 sampled on a grid of spacing 0.02, the samples
        // shifted in z by ±sigma alternately: an off-surface point at 3σ on
        // the side its sample leans away from is nearer (0.022) to the
        // neighbours leaning the other way than 0.9·y = 0.027.
        let sigma = 0.01;
        let mut points = Vec::new();
        for i in 0..60 {
            for j in 0..60 {
                let shift = if (i + j) % 2 == 0 { sigma } else { -sigma };
                points.push(DVec3::new(i as f64 * 0.02, j as f64 * 0.02, shift));
            }
        }
        let normals = vec![DVec3::Z; points.len()];
        let mut s = SurfaceSamples::new(&points, &normals).unwrap();
        let reps: Vec<usize> = (0..points.len()).collect();
        let y = 3.0 * sigma;
        let at_y = |pts: &[TrainingPoint]| pts.iter().filter(|p| p.target.abs() == y).count();
        let strict = at_y(&s.off_surface(&reps, y));
        s.set_noise(sigma);
        let allowing = s.off_surface(&reps, y);
        assert!(strict <= points.len(), "strict check kept {strict}");
        assert!(
            at_y(&allowing) > 19 * 2 * points.len() / 20,
            "{}",
            at_y(&allowing)
        );
        // Still a real check: nothing closer than half its offset survives.
        for p in &allowing {
            let nearest = s.tree.nearest(p.position).unwrap().distance;
            assert!(nearest >= 0.5 * p.target.abs());
        }
    }

    #[test]
    fn isolated_samples_and_disagreeing_normals_are_found() {
        let pc = sample_surface(&icosphere(DVec3::ZERO, 1.0, 3), 4000, 6);
        let mut points = pc.positions.clone();
        let mut normals = pc.normals.clone().unwrap();
        // A stray point far out, and a surface sample with a flipped normal.
        points.push(DVec3::new(3.0, 0.0, 0.0));
        normals.push(DVec3::X);
        normals[0] = -normals[0];
        let s = SurfaceSamples::new(&points, &normals).unwrap();
        let kept = s.unisolated(4.0);
        assert_eq!(kept.len(), points.len() - 1);
        assert!(!kept.contains(&(points.len() - 1)));
        assert!(!s.normal_agrees[0]);
        let agreeing = s.normal_agrees.iter().filter(|a| **a).count();
        assert!(agreeing >= points.len() - 3, "{agreeing}");
        assert!(s.off_surface(&[0], 0.05).is_empty());
    }

    #[test]
    fn box_representatives_pick_one_point_per_cube() {
        let pc = sample_surface(&icosphere(DVec3::ZERO, 1.0, 3), 5000, 2);
        let origin = DVec3::splat(-1.0);
        let h = 0.25;
        let reps = box_representatives(&pc.positions, origin, h);
        let cube = |p: DVec3| ((p - origin) / h).floor().as_ivec3();
        assert_eq!(reps.iter().map(|r| r.1).sum::<usize>(), pc.len());
        let mut cubes: Vec<_> = reps.iter().map(|&(i, _)| cube(pc.positions[i])).collect();
        let n = cubes.len();
        cubes.sort_by_key(|c| (c.x, c.y, c.z));
        cubes.dedup();
        assert_eq!(cubes.len(), n, "two representatives in one cube");
        let mut all: Vec<_> = pc.positions.iter().map(|&p| cube(p)).collect();
        all.sort_by_key(|c| (c.x, c.y, c.z));
        all.dedup();
        assert_eq!(all.len(), n, "an occupied cube without representative");
    }

    #[test]
    fn rejects_bad_input() {
        let p = vec![DVec3::ZERO; 5];
        let n = vec![DVec3::Z; 5];
        assert!(SurfaceSamples::new(&p[..3], &n[..3]).is_err());
        assert!(SurfaceSamples::new(&p, &n[..4]).is_err());
        assert!(SurfaceSamples::new(&p, &n).is_err()); // no extent
        let mut q: Vec<DVec3> = (0..5).map(|i| DVec3::splat(i as f64)).collect();
        let mut m = n.clone();
        m[2] = DVec3::ZERO;
        assert!(SurfaceSamples::new(&q, &m).is_err());
        q[1].x = f64::NAN;
        assert!(SurfaceSamples::new(&q, &n).is_err());
    }
}
