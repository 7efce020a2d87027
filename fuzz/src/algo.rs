//! Checks of the algorithm targets: the library calls behind
//! `reconstruct` (each method, through the `surfrecon` facade), `distance`
//! (regular, signed, odf, udf), `extract`, `normals` and `eval` on the
//! small structured inputs of [`crate::scene`], with arbitrary (often
//! absurd) options. Each call must either return an error with a message
//! or a result that keeps its promise: a closed manifold mesh, distances
//! that agree with brute force, unit normals, finite scores.

use crate::scene::{self, pick_f64};
use arbitrary::{Result, Unstructured};
use surfrecon_geom::metrics::topology;
use surfrecon_geom::{DVec3, TriMesh};

/// With `SURFRECON_FUZZ_SHOW` set (replaying one input), print what the
/// bytes decoded to, to turn a finding into a regression test.
pub fn show(what: &str, value: &dyn std::fmt::Debug) {
    if std::env::var_os("SURFRECON_FUZZ_SHOW").is_some() {
        eprintln!("{what}: {value:#?}");
    }
}

/// An error must say something.
fn clear_error(e: impl std::fmt::Display, what: &str) {
    let message = e.to_string();
    assert!(
        !message.trim().is_empty(),
        "{what}: error without a message"
    );
}

/// Finite vertices, indices in range, every edge in exactly two faces,
/// one fan around every vertex.
pub fn assert_closed_manifold(mesh: &TriMesh, what: &str) {
    if let Some(v) = mesh.vertices.iter().find(|v| !v.is_finite()) {
        panic!("{what}: non-finite vertex {v}");
    }
    let n = mesh.vertices.len();
    if let Some(t) = mesh
        .triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= n))
    {
        panic!("{what}: triangle {t:?} indexes past {n} vertices");
    }
    let t = topology(mesh);
    assert!(
        t.watertight && t.edge_manifold && t.vertex_manifold,
        "{what}: the surface is not a closed manifold: {t:?}"
    );
}

/// A non-empty manifold mesh whose holes have `reported` edges in all.
fn assert_manifold_with_holes(mesh: &TriMesh, reported: usize) {
    assert!(!mesh.triangles.is_empty(), "an empty mesh is not a surface");
    let t = topology(mesh);
    assert!(
        t.edge_manifold && t.vertex_manifold && t.boundary_edges == reported,
        "convection: not manifold, or {reported} boundary edges reported: {t:?}"
    );
}

/// A grid resolution: mostly 4–`max`, sometimes absurd (0–3, huge).
fn resolution(u: &mut Unstructured, max: usize) -> Result<usize> {
    Ok(match u.int_in_range(0..=15)? {
        0 => u.int_in_range(0..=3)?,
        1 => *u.choose(&[100_001, usize::MAX])?,
        _ => u.int_in_range(4..=max)?,
    })
}

/// Which reconstruction method a target drives.
#[derive(Clone, Copy, Debug)]
pub enum MethodKind {
    LevelSet,
    Svm,
    Convection,
}

/// `surfrecon::reconstruct` on a small input with arbitrary options of
/// `kind`: an error, or a closed manifold mesh (3D) / closed curves (2D).
pub fn reconstruct(data: &[u8], kind: MethodKind) {
    let mut u = Unstructured::new(data);
    let Ok(Some((input, options))) = reconstruct_case(&mut u, kind) else {
        return;
    };
    show("input", &input);
    show("options", &options);
    let result = surfrecon::reconstruct(&input, &options);
    show("result", &result.as_ref().map(|o| &o.mesh));
    match result {
        Err(e) => clear_error(e, "reconstruct"),
        Ok(output) => match &output.curves {
            Some(curves) => {
                assert!(!curves.lines.is_empty(), "2D reconstruction gave no curve");
                for line in &curves.lines {
                    assert!(
                        line.len() > 3 && line.first() == line.last(),
                        "2D reconstruction gave an open curve {line:?}"
                    );
                }
            }
            None => match &output.report {
                // Convection interpolates the points and leaves holes where
                // the sampling is too sparse, reporting their edges.
                surfrecon::Report::Convection(r) => {
                    assert_manifold_with_holes(&output.mesh, r.convection.boundary_edges)
                }
                _ => assert_closed_manifold(&output.mesh, "reconstruct"),
            },
        },
    }
}

fn reconstruct_case(
    u: &mut Unstructured,
    kind: MethodKind,
) -> Result<Option<(surfrecon::Input, surfrecon::Options)>> {
    use surfrecon::*;
    let Some(input) = scene::geometry(u, 48)? else {
        return Ok(None);
    };
    let method = match kind {
        MethodKind::LevelSet => Method::LevelSet(levelset_options(u)?),
        MethodKind::Svm => Method::Svm(svm_options(u)?),
        MethodKind::Convection => Method::Convection(convection_options(u)?),
    };
    let options = Options {
        method,
        resolution: Some(resolution(u, 16)?),
        curve_network: u.arbitrary()?,
        join_pieces: u.arbitrary()?,
        data_fit: u.arbitrary()?,
    };
    Ok(Some((input, options)))
}

fn levelset_options(u: &mut Unstructured) -> Result<surfrecon::LevelSetOptions> {
    use surfrecon::{FieldOutput, LevelSetOptions};
    let d = LevelSetOptions::default();
    Ok(LevelSetOptions {
        epsilon: match u.arbitrary()? {
            true => Some(pick_f64(u, &[0.01, 0.1, 1.0, 0.0, -1.0, 1e300])?),
            false => None,
        },
        p: pick_f64(u, &[d.p, 1.0, 4.0, 0.5])?,
        steps: u.int_in_range(0..=40)?,
        // A wide band pads the grid by as many cells (band 64 at
        // resolution 15: a 148 x 154 x 154 grid, seconds per run).
        band: match pick_f64(u, &[d.band, 2.0, 8.0, 1.0, 65.0])? {
            b if (12.0..=64.0).contains(&b) => 12.0,
            b => b,
        },
        // More levels multiply the work (5 levels at resolution 4 on flat
        // data took over 10 s): at most 2, or invalid ones.
        levels: match u.arbitrary()? {
            true => Some(*u.choose(&[0, 1, 2, 7])?),
            false => None,
        },
        bounding_box: u.arbitrary()?,
        free_topology: u.arbitrary()?,
        cleaning: u.arbitrary()?,
        refine: u.arbitrary()?,
        slices: u.arbitrary()?,
        two_d: u.ratio(1, 8)?,
        field: *u.choose(&[FieldOutput::None, FieldOutput::Band, FieldOutput::Full])?,
    })
}

fn svm_options(u: &mut Unstructured) -> Result<surfrecon::SvmOptions> {
    use surfrecon::{Loss, SvmC, SvmOptions};
    let d = SvmOptions::default();
    Ok(SvmOptions {
        // Parameter selection fits many models: rarely.
        c: match u.ratio(1, 16)? {
            true => SvmC::Auto,
            false => SvmC::Fixed(pick_f64(u, &[1.0, 0.1, 100.0, 0.0, -1.0])?),
        },
        epsilon: pick_f64(u, &[d.epsilon, 0.0, 0.01, 0.5, -1.0])?,
        accuracy: pick_f64(u, &[d.accuracy, 0.01, 0.1, 0.0, -1.0])?,
        loss: *u.choose(&[Loss::Epsilon, Loss::Squared])?,
        drop_levels: u.int_in_range(0..=3)?,
        model_out: None,
        model_in: None,
        normal_k: u.int_in_range(0..=16)?,
        cleaning: u.arbitrary()?,
    })
}

fn convection_options(u: &mut Unstructured) -> Result<surfrecon::ConvectionOptions> {
    use surfrecon::ConvectionOptions;
    let d = ConvectionOptions::default();
    Ok(ConvectionOptions {
        rho: pick_f64(u, &[0.0, 0.0, 0.05, 0.3, 2.0, -1.0])?,
        rho_geom: pick_f64(u, &[d.rho_geom, 0.0, 1.0, -1.0])?,
        rho_topo: pick_f64(u, &[d.rho_topo, 1.0, 0.0])?,
        decimate_on_the_fly: u.arbitrary()?,
        fill_holes: u.int_in_range(0..=30)?,
        pockets: u.arbitrary()?,
        thin_parts: u.arbitrary()?,
        normal_k: u.int_in_range(0..=16)?,
        brush: None,
        refine_alpha: pick_f64(u, &[d.refine_alpha, 1.0, 0.5, -1.0])?,
        refine_gamma: pick_f64(u, &[d.refine_gamma, 0.5, -1.0])?,
        open_holes: u.arbitrary()?,
        edge_flips: u.arbitrary()?,
        split_curved_edges: u.arbitrary()?,
    })
}

/// `normals`: estimation with and without orientation, any `k`: one finite
/// unit normal per point, and orientation changes only signs.
pub fn normals(data: &[u8]) {
    use surfrecon_geom::normals::{estimate_normals, estimate_oriented_normals, orient_normals};
    let mut u = Unstructured::new(data);
    let Ok((_, mut points)) = scene::layout_points(&mut u, 64) else {
        return;
    };
    let (Ok(true), Ok(k)) = (
        scene::place(&mut u, &mut points),
        u.int_in_range(0..=24usize),
    ) else {
        return;
    };
    let plain = estimate_normals(&points, k);
    let oriented = estimate_oriented_normals(&points, k);
    let mut flipped = plain.clone();
    orient_normals(&points, &mut flipped, k);
    for (name, set) in [
        ("estimated", &plain),
        ("oriented", &oriented),
        ("flipped", &flipped),
    ] {
        assert_eq!(set.len(), points.len(), "{name}: one normal per point");
        for n in set.iter() {
            assert!(
                n.is_finite() && (n.length() - 1.0).abs() < 1e-9,
                "{name} normal {n} is not a finite unit vector (k = {k})"
            );
        }
    }
    for (a, b) in plain.iter().zip(&flipped) {
        assert!(
            *a == *b || *a == -*b,
            "orientation changed more than a sign"
        );
    }
}

/// `eval`: compare two arbitrary surfaces (meshes or point sets) and
/// measure data against a mesh: an error, or finite scores in range; a
/// point set compared with itself scores perfectly.
pub fn eval(data: &[u8]) {
    use surfrecon_geom::data_fit::data_fit;
    use surfrecon_geom::metrics::{evaluate, EvalOptions, Surface};
    let mut u = Unstructured::new(data);
    let (Ok(Some(a)), Ok(Some(b))) = (scene::geometry(&mut u, 32), scene::geometry(&mut u, 32))
    else {
        return;
    };
    let options = EvalOptions {
        samples: u.int_in_range(0..=300).unwrap_or(1),
        seed: u.arbitrary().unwrap_or(0),
    };
    show("candidate", &a);
    show("reference", &b);
    let (a, b) = (Surface::from(a), Surface::from(b));
    match evaluate(&a, &b, &options) {
        Err(e) => clear_error(e, "evaluate"),
        Ok(r) => {
            // Squared distances past 1e154 overflow: the true value is
            // beyond the f64 range.
            let huge = r.hausdorff > 1e150;
            assert!(
                r.chamfer_l2 >= 0.0 && (r.chamfer_l2.is_finite() || huge),
                "{r:?}"
            );
            for (name, v) in [
                ("chamfer L1", r.chamfer_l1),
                ("hausdorff", r.hausdorff),
                ("diagonal", r.diagonal),
            ] {
                assert!(v.is_finite() && v >= 0.0, "{name} = {v}");
            }
            for f in [r.fscore_0_5pct, r.fscore_1pct] {
                assert!((0.0..=1.0).contains(&f), "F-score {f}");
            }
            if let Some(nc) = r.normal_consistency {
                assert!((0.0..=1.0 + 1e-12).contains(&nc), "normal consistency {nc}");
            }
            assert!(
                r.chamfer_l1 <= r.hausdorff * (1.0 + 1e-12),
                "mean above max: {r:?}"
            );
        }
    }
    if let Surface::Points(p) = &a {
        if let Ok(r) = evaluate(&a, &a, &options) {
            assert_eq!(r.chamfer_l1, 0.0, "a point set against itself: {r:?}");
            assert_eq!(r.fscore_1pct, 1.0, "a point set against itself: {r:?}");
        }
        if let Surface::Mesh(mesh) = &b {
            match data_fit(mesh, &p.positions) {
                Err(e) => clear_error(e, "data fit"),
                Ok(fit) => {
                    // The mean may exceed the max by rounding when all are equal.
                    assert!(
                        fit.mean >= 0.0 && fit.mean <= fit.max * (1.0 + 1e-12),
                        "{fit:?}"
                    );
                    assert!(fit.max.is_finite() || fit.diagonal == 0.0, "{fit:?}");
                }
            }
        }
    }
}

/// `distance` (regular kind): unsigned distances in 2D or 3D to points,
/// segments and triangles, narrow band or propagated, against brute force;
/// signed distances of meshes, with the sign checked on convex ones.
pub fn distance(data: &[u8]) {
    let mut u = Unstructured::new(data);
    let _ = distance_case(&mut u);
}

fn distance_case(u: &mut Unstructured) -> Result<()> {
    use surfrecon_grid::distance::{DataSet, DistanceOptions};
    let signed = u.ratio(1, 3)?;
    if signed {
        return signed_case(u);
    }
    let Some(geometry) = scene::geometry(u, 24)? else {
        return Ok(());
    };
    let options = DistanceOptions {
        band_cells: pick_f64(u, &[3.0, 0.0, 0.5, 1.0, 10.0])?,
        propagate: u.arbitrary()?,
    };
    let size = grid_size(u)?;
    let padding = u.int_in_range(0..=4)?;
    if u.arbitrary()? {
        match DataSet::<2>::from_geometry(&geometry) {
            Err(e) => clear_error(e, "2D data set"),
            Ok(data) => unsigned_case(&data, size, padding, &options),
        }
    } else {
        match DataSet::<3>::from_geometry(&geometry) {
            Err(e) => clear_error(e, "3D data set"),
            Ok(data) => unsigned_case(&data, size, padding, &options),
        }
    }
    Ok(())
}

/// `--resolution` (mostly 1–16) or `--spacing` (a fraction of a unit
/// layout, possibly absurd).
fn grid_size(u: &mut Unstructured) -> Result<surfrecon_grid::GridSize> {
    use surfrecon_grid::GridSize;
    Ok(if u.ratio(1, 4)? {
        GridSize::Spacing(pick_f64(u, &[0.5, 1.0, 0.0, -1.0, 1e-300, 1e300])?)
    } else {
        GridSize::Resolution(resolution(u, 16)?)
    })
}

fn unsigned_case<const D: usize>(
    data: &surfrecon_grid::distance::DataSet<D>,
    size: surfrecon_grid::GridSize,
    padding: usize,
    options: &surfrecon_grid::distance::DistanceOptions,
) {
    use surfrecon_grid::distance::unsigned_distance_with;
    use surfrecon_grid::GridSpec;
    let Some((lo, hi)) = data.bounds() else {
        return;
    };
    let spec = match GridSpec::from_bounds(lo, hi, size, padding) {
        Ok(spec) if spec.node_count() <= 40_000 => spec,
        Ok(_) => return,
        Err(e) => return clear_error(e, "grid"),
    };
    show("data", data);
    show("grid", &(&spec, options));
    let field = match unsigned_distance_with(data, &spec, options) {
        Ok(f) => f.field,
        Err(e) => return clear_error(e, "unsigned distance"),
    };
    let h = spec.spacing;
    let band = options.band_cells * h;
    let magnitude = lo.iter().chain(&hi).fold(h, |m, c| m.max(c.abs()));
    let tol = 1e-9 * magnitude;
    // Far from segments and triangles a value comes from a foot stored in
    // f32 cell coordinates: below the true distance by rounding only.
    let below = tol + 1e-5 * h;
    let s = unit_power_of_two(magnitude);
    let times = |p: &[f64; D]| p.map(|c| c * s);
    let unit = data.scaled(s);
    for (node, &value) in field.values.iter().enumerate() {
        let p = times(&spec.position(spec.unlinear(node)));
        let exact = (0..unit.len())
            .map(|i| unit.distance(i, &p))
            .fold(f64::INFINITY, f64::min)
            / s;
        if !exact.is_finite() {
            continue; // the distance itself overflows (coordinates near 1e300)
        }
        assert!(
            value >= exact - below,
            "node {node}: {value} below the true distance {exact}"
        );
        // The band ranks data by f32 squared distances: its value is the
        // exact distance to a datum at most 6e-8 (relative) farther than
        // the nearest (a 1e-8 mesh seen from 0.43 away: 7e-9).
        if exact <= band - tol {
            assert!(
                value - exact <= tol + 1e-7 * exact,
                "node {node}: {value} within the exact band ({band}) but the true distance is {exact}"
            );
        }
        if options.propagate {
            assert!(
                value <= exact + 0.2 * h + tol,
                "node {node}: {value} more than 0.2 h above the true distance {exact} (h = {h})"
            );
        }
    }
}

fn signed_case(u: &mut Unstructured) -> Result<()> {
    use surfrecon_grid::sdf::signed_distance;
    use surfrecon_grid::GridSpec;
    let (mesh, convex) = if u.ratio(3, 4)? {
        match scene::closed_mesh(u)? {
            Some(m) => m,
            None => return Ok(()),
        }
    } else {
        let Some(g) = scene::geometry(u, 24)? else {
            return Ok(());
        };
        (g.to_mesh(), false)
    };
    let size = grid_size(u)?;
    let padding = u.int_in_range(0..=4)?;
    let band_cells = match u.arbitrary()? {
        true => Some(pick_f64(u, &[1.0, 2.0, 3.0, 0.5, 0.0])?),
        false => None,
    };
    let bounds = mesh_bounds(&mesh);
    let spec = match GridSpec::from_bounds(bounds.0, bounds.1, size, padding) {
        Ok(spec) if spec.node_count() <= 40_000 => spec,
        Ok(_) => return Ok(()),
        Err(e) => return Ok(clear_error(e, "grid")),
    };
    let h = spec.spacing;
    let band = band_cells.map(|c| c * h);
    show("mesh", &mesh);
    show("grid", &(&spec, band));
    let field = match signed_distance(&mesh, &spec, band) {
        Ok(f) => f,
        Err(e) => return Ok(clear_error(e, "signed distance")),
    };
    let magnitude = bounds
        .0
        .iter()
        .chain(&bounds.1)
        .fold(h, |m, c| m.max(c.abs()));
    let tol = 1e-9 * magnitude;
    let below = tol + 1e-5 * h; // f32 feet, as in `unsigned_case`
    let s = unit_power_of_two(magnitude);
    let unit = TriMesh {
        vertices: mesh.vertices.iter().map(|v| *v * s).collect(),
        ..mesh.clone()
    };
    for (node, &value) in field.values.iter().enumerate() {
        let p = DVec3::from_array(spec.position(spec.unlinear(node)));
        let exact = unit
            .triangles
            .iter()
            .map(|t| point_triangle_distance(p * s, unit.corners_of(t)))
            .fold(f64::INFINITY, f64::min)
            / s;
        if !exact.is_finite() {
            continue;
        }
        let cap = band.unwrap_or(f64::INFINITY);
        assert!(
            value.abs() >= exact.min(cap) - below,
            "node {node}: |{value}| below the true distance {exact}"
        );
        if convex && exact > 1e-6 * magnitude {
            let inside = unit
                .triangles
                .iter()
                .all(|t| outward_side(p * s, unit.corners_of(t)) < 0.0);
            assert_eq!(
                value < 0.0,
                inside,
                "node {node} at {p}: value {value}, inside the convex mesh: {inside}"
            );
        }
    }
    Ok(())
}

/// A power of two bringing `magnitude` near 1: the brute-force distances
/// are computed on scaled copies (exactly), since squares of differences
/// near 1e150 leave the f64 range.
fn unit_power_of_two(magnitude: f64) -> f64 {
    2f64.powi(-(magnitude.log2().floor() as i32).clamp(-1000, 1000))
}

trait Corners {
    fn corners_of(&self, t: &[u32; 3]) -> [DVec3; 3];
}

impl Corners for TriMesh {
    fn corners_of(&self, t: &[u32; 3]) -> [DVec3; 3] {
        t.map(|i| {
            self.vertices
                .get(i as usize)
                .copied()
                .unwrap_or(DVec3::ZERO)
        })
    }
}

fn point_triangle_distance(p: DVec3, t: [DVec3; 3]) -> f64 {
    surfrecon_geom::metrics::closest_point_on_triangle(p, t).distance(p)
}

/// Signed volume of p with the face (positive on the side the face's
/// normal points to, for a counter-clockwise face seen from outside).
fn outward_side(p: DVec3, [a, b, c]: [DVec3; 3]) -> f64 {
    (b - a).cross(c - a).dot(p - a)
}

fn mesh_bounds(mesh: &TriMesh) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for v in &mesh.vertices {
        for a in 0..3 {
            lo[a] = lo[a].min(v[a]);
            hi[a] = hi[a].max(v[a]);
        }
    }
    (lo, hi)
}

/// `distance --kind odf|udf` then `extract`: from a closed mesh, either
/// an error or a field whose surface is a closed manifold mesh.
pub fn feature_field(data: &[u8]) {
    use surfrecon_distfield::offset::{build_odf, OdfOptions, Weights};
    use surfrecon_distfield::unified::{build_udf, UdfOptions};
    let mut u = Unstructured::new(data);
    let Ok(Some((mesh, _))) = scene::closed_mesh(&mut u) else {
        return;
    };
    let (Ok(size), Ok(padding), Ok(angle), Ok(odf)) = (
        grid_size(&mut u),
        u.int_in_range(0..=3usize),
        pick_f64(&mut u, &[30.0, 0.0, 90.0, 180.0]),
        u.arbitrary::<bool>(),
    ) else {
        return;
    };
    // Keep each run short (the feature search is per cell): at most
    // 12^3 cells; grids refused here are refused by the builders too.
    let (lo, hi) = mesh_bounds(&mesh);
    if let Ok(spec) = surfrecon_grid::GridSpec::from_bounds(lo, hi, size, padding) {
        if spec.node_count() > 13 * 13 * 13 {
            return;
        }
    }
    show("mesh", &mesh);
    show("size, padding, angle", &(size, padding, angle));
    let extracted = if odf {
        let options = OdfOptions {
            size,
            padding,
            feature_angle_deg: angle,
            weights: Weights {
                distance: pick_f64(&mut u, &[1.0, 0.0, -1.0]).unwrap_or(1.0),
                spring: pick_f64(&mut u, &[0.1, 0.0]).unwrap_or(0.1),
                ortho: pick_f64(&mut u, &[0.1, 0.0]).unwrap_or(0.1),
            },
            iterations: u.int_in_range(0..=8).unwrap_or(0),
        };
        show("odf options", &options);
        build_odf(&mesh, &options).map(|(f, _)| f.extract().0)
    } else {
        let options = UdfOptions {
            size,
            padding,
            threshold: pick_f64(&mut u, &[0.05, 0.0, 1.0, -1.0]).unwrap_or(0.05),
            feature_angle_deg: angle,
        };
        show("udf options", &options);
        build_udf(&mesh, &options).map(|(f, _)| f.extract().0)
    };
    match extracted {
        Err(e) => clear_error(e, "feature field"),
        Ok(surface) if surface.triangles.is_empty() => {} // `extract` refuses it
        // Without padding the surface meets the grid's border and is cut
        // open there (`extract` reports it as open).
        Ok(surface) if padding == 0 => {
            let t = topology(&surface);
            assert!(t.edge_manifold, "feature field surface: {t:?}");
        }
        Ok(surface) => assert_closed_manifold(&surface, "feature field surface"),
    }
}

/// `extract` (marching cubes / squares) on small arbitrary fields: when
/// every border node is below `iso`, the surface is closed and manifold
/// (curves closed), every vertex inside the grid.
pub fn extract(data: &[u8]) {
    let mut u = Unstructured::new(data);
    let _ = extract_case(&mut u);
}

fn extract_case(u: &mut Unstructured) -> Result<()> {
    use surfrecon_grid::marching::{marching_cubes, marching_squares};
    use surfrecon_grid::{Field, GridSpec};
    let three_d: bool = u.arbitrary()?;
    let dims: Vec<usize> = (0..if three_d { 3 } else { 2 })
        .map(|_| u.int_in_range(2..=7))
        .collect::<Result<_>>()?;
    let nodes: usize = dims.iter().product();
    let mut values = Vec::with_capacity(nodes);
    for _ in 0..nodes {
        values.push(f64::from(u.int_in_range(-4i8..=4)?));
    }
    let iso = pick_f64(u, &[0.0, 0.5, -1.0, 1.0])?;
    if !iso.is_finite() {
        return Ok(()); // `extract` refuses it before marching
    }
    let spacing = 10f64.powi(*u.choose(&[0, 0, -6, 6, -300, 300])?);
    // Closing the border needs a value below iso (not so at ±1e300).
    let closed_border = u.arbitrary::<bool>()? && iso - 1.0 < iso;
    if three_d {
        let spec = GridSpec {
            origin: [0.0; 3],
            spacing,
            dims: [dims[0], dims[1], dims[2]],
        };
        let mut field = Field { spec, values };
        if closed_border {
            close_border(&mut field.values, &spec.dims, iso);
        }
        let mesh = marching_cubes(&field, iso);
        let top = spec.max_corner();
        for v in &mesh.vertices {
            assert!(
                (0..3).all(|a| v[a] >= 0.0 && v[a] <= top[a]),
                "vertex {v} outside the grid"
            );
        }
        if closed_border && !mesh.triangles.is_empty() {
            assert_closed_manifold(&mesh, "marching cubes");
        }
    } else {
        let spec = GridSpec {
            origin: [0.0; 2],
            spacing,
            dims: [dims[0], dims[1]],
        };
        let mut field = Field { spec, values };
        if closed_border {
            close_border(&mut field.values, &spec.dims, iso);
        }
        let curves = marching_squares(&field, iso);
        if closed_border {
            for line in &curves.lines {
                assert!(
                    line.len() > 3 && line.first() == line.last(),
                    "open curve {line:?} in a field below iso on its border"
                );
            }
        }
    }
    Ok(())
}

/// Set every border node below `iso` (so no level crosses the border).
fn close_border<const D: usize>(values: &mut [f64], dims: &[usize; D], iso: f64) {
    let mut idx = [0usize; D];
    for v in values.iter_mut() {
        if (0..D).any(|a| idx[a] == 0 || idx[a] + 1 == dims[a]) {
            *v = iso - 1.0;
        }
        for a in 0..D {
            idx[a] += 1;
            if idx[a] < dims[a] {
                break;
            }
            idx[a] = 0;
        }
    }
}
