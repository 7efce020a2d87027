//! The module's functions. Docstrings here are what `help()` shows; the
//! stubs in surfrecon.pyi carry the same signatures with types.

use crate::arrays::{indices, to_indices, to_vertices, vectors};
use crate::errors::{self, value_error};
use crate::hook::Watch;
use numpy::ndarray::{Array3, ShapeBuilder};
use numpy::{IntoPyArray, PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use std::path::PathBuf;
use surfrecon::geom::metrics::{self, EvalOptions, Surface};
use surfrecon::grid::distance::{unsigned_distance_with, DataSet, DistanceOptions};
use surfrecon::grid::GridSize;
use surfrecon::{
    ConvectionOptions, Geometry, LevelSetOptions, Method, Options, PointCloud, SvmOptions, TriMesh,
};

/// Points (an (N, 3) array) or a mesh (a (vertices, faces) tuple).
enum Shape {
    Points(Vec<surfrecon::DVec3>),
    Mesh(TriMesh),
}

fn shape(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Shape> {
    if let Ok(t) = obj.cast::<PyTuple>() {
        if t.len() != 2 {
            return Err(value_error(format!(
                "{name} must be an (N, 3) array or a (vertices, faces) tuple, got a tuple of {}",
                t.len()
            )));
        }
        return mesh(&t.get_item(0)?, &t.get_item(1)?, name).map(Shape::Mesh);
    }
    vectors(obj, name).map(Shape::Points)
}

fn mesh(v: &Bound<'_, PyAny>, f: &Bound<'_, PyAny>, name: &str) -> PyResult<TriMesh> {
    let vertices = vectors(v, &format!("{name} vertices"))?;
    let triangles = indices::<3>(f, &format!("{name} faces"), vertices.len())?;
    Ok(TriMesh {
        vertices,
        triangles,
        normals: None,
    })
}

/// The data as one geometry: points (with normals), then every curve's
/// vertices with a polyline over them, then the patches' vertices.
fn input_geometry(
    points: Option<&Bound<'_, PyAny>>,
    normals: Option<&Bound<'_, PyAny>>,
    curves: Option<&Bound<'_, PyAny>>,
    triangles: Option<&Bound<'_, PyAny>>,
) -> PyResult<Geometry> {
    let mut g = Geometry::default();
    if let Some(p) = points {
        g.points.positions = vectors(p, "points")?;
    }
    if let Some(n) = normals {
        let n = vectors(n, "normals")?;
        if points.is_none() || n.len() != g.points.positions.len() {
            return Err(value_error(format!(
                "normals must have one row per point: {} normals for {} points",
                n.len(),
                g.points.positions.len()
            )));
        }
        g.points.normals = Some(n);
    }
    if let Some(curves) = curves {
        for (i, c) in curves.try_iter()?.enumerate() {
            let c = vectors(&c?, &format!("curves[{i}]"))?;
            let start = g.points.positions.len() as u32;
            g.lines.push((start..start + c.len() as u32).collect());
            g.points.positions.extend(c);
        }
    }
    if let Some(t) = triangles {
        let Shape::Mesh(m) = shape(t, "triangles")? else {
            return Err(value_error("triangles must be a (vertices, faces) tuple"));
        };
        let start = g.points.positions.len() as u32;
        g.triangles
            .extend(m.triangles.iter().map(|t| t.map(|i| i + start)));
        g.points.positions.extend(m.vertices);
    }
    if g.points.normals.is_some() && (!g.lines.is_empty() || !g.triangles.is_empty()) {
        // Normals belong to the points only; the methods read them only
        // when every vertex has one.
        g.points.normals = None;
    }
    Ok(g)
}

/// Ctrl-C, `cancel` and `progress` for one run: `run` gets the hook.
fn watched<T: Send>(
    py: Python<'_>,
    cancel: Option<Py<PyAny>>,
    progress: Option<Py<PyAny>>,
    run: impl Send + FnOnce(surfrecon::Hook) -> surfrecon::Result<T>,
) -> PyResult<T> {
    let watch = Watch::new(cancel, progress);
    let result = py.detach(|| run(&|p| watch.report(p)));
    result.map_err(|e| match (e.kind, watch.take_raised()) {
        (surfrecon::ErrorKind::Cancelled, Some(raised)) => raised,
        _ => errors::to_py(e),
    })
}

fn method_options(method: &str, m: MethodArgs) -> PyResult<Method> {
    Ok(match method {
        "levelset" => Method::LevelSet(m.levelset),
        "svm" => Method::Svm(m.svm),
        "convection" => Method::Convection(m.convection),
        other => {
            return Err(value_error(format!(
            "invalid value {other:?} for method: expected \"levelset\", \"svm\" or \"convection\""
        )))
        }
    })
}

struct MethodArgs {
    levelset: LevelSetOptions,
    svm: SvmOptions,
    convection: ConvectionOptions,
}

fn parse_svm_c(c: Option<&Bound<'_, PyAny>>) -> PyResult<surfrecon::SvmC> {
    let Some(c) = c else {
        return Ok(SvmOptions::default().c);
    };
    if let Ok(s) = c.extract::<String>() {
        if s.eq_ignore_ascii_case("auto") {
            return Ok(surfrecon::SvmC::Auto);
        }
    }
    match c.extract::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(surfrecon::SvmC::Fixed(v)),
        _ => Err(value_error(format!(
            "invalid value for svm_c: expected a positive number or \"auto\", got {c}"
        ))),
    }
}

fn loss(name: &str) -> PyResult<surfrecon::Loss> {
    match name {
        "epsilon" => Ok(surfrecon::Loss::Epsilon),
        "squared" => Ok(surfrecon::Loss::Squared),
        other => Err(value_error(format!(
            "invalid value {other:?} for loss: expected \"epsilon\" or \"squared\""
        ))),
    }
}

/// Reconstruct a closed surface from points, curves and triangle patches.
///
/// Data (any mix; float32 or float64, C or Fortran order):
///   points     (N, 3) array of points.
///   normals    (N, 3) array of point normals (optional; svm and
///              convection estimate them when absent).
///   curves     list of (K, 3) arrays, one polyline each.
///   triangles  (vertices, faces) tuple: surface patches.
///
/// Returns (V, F): float64 (n, 3) vertices and int64 (m, 3) triangles; for
/// planar data with the level set (all z equal, or two_d=True), closed
/// curves: V and int64 (m, 2) segments. With report=True, (V, F, report)
/// where report is the dict `surfrecon reconstruct --json` prints (less
/// command/input/output; "data_fit" measured).
///
/// Common options:
///   method      "levelset" (default), "svm" or "convection". Crossing
///               curve networks are spanned by a Hermite fit whatever the
///               method (no_curve_network=True to prevent it); pieces the
///               curves do not keep apart are joined (keep_pieces=True
///               to prevent it).
///   resolution  grid cells along the longest axis [level set: from the
///               sampling density; svm: 200].
///   cancel      an object with is_set() (threading.Event): the run stops
///               with surfrecon.Cancelled soon after it is set. Ctrl-C
///               stops it with KeyboardInterrupt.
///   progress    called as progress(stage, done, total) between stages and
///               iterations; returning False cancels.
///
/// Level set (method="levelset"), defaults as the command line:
///   epsilon=None (from the sampling density) offset of the initial
///     contour; p=1.0 exponent of the weighted area energy; steps=100 flow
///     steps per level; band=3.0 narrow band half-width in cells;
///   levels=None resolution levels; bounding_box=False exterior outside the
///     data box; free_topology=False let the topology change;
///     no_cleaning=False keep outliers and noise; no_refine=False no
///     snapping/fairing; no_slices=False evolve contour stacks in 3D;
///     two_d=False closed curves in the xy plane.
/// SVM (method="svm"):
///   svm_c=1.0 (or "auto": C and epsilon by validation); svm_epsilon=1e-4
///   tube width / diagonal; svm_accuracy=2e-4 fit accuracy / diagonal;
///   loss="epsilon" or "squared"; drop_levels=0 finest levels left out;
///   model_out=None / model_in=None .svm model file; svm_normal_k=12.
/// Convection (method="convection"):
///   rho=0.0 decimation radius / diagonal; rho_geom=0.9; rho_topo=0.95;
///   on_the_fly=False decimate in the order a convection front reaches the
///   points (the paper's scheme; closer fit, slower) instead of input order
///   (noisy points: input order still);
///   fill_holes=24 largest hole (edges) closed; no_pockets=False;
///   no_thin_parts=False; convection_normal_k=12; cover_holes=False cover
///   the holes in the sampling (no sample inside) instead of leaving them
///   open as boundary edges;
///   no_edge_flips=False keep the convection's triangles (no flips that
///   lower the bending); no_curved_splits=False keep the input points as
///   the only vertices (no new vertices on edges where the smooth surface
///   bends away from them).
///
/// Raises ValueError for bad arrays or options (the command line's
/// messages), OSError for model files, surfrecon.Cancelled when cancelled.
#[pyfunction]
#[pyo3(signature = (
    points=None, normals=None, curves=None, triangles=None, *,
    method="levelset", resolution=None, report=false, cancel=None, progress=None,
    epsilon=None, p=None, steps=None, band=None, levels=None, bounding_box=false,
    free_topology=false, no_cleaning=false, no_refine=false, no_slices=false,
    no_curve_network=false, keep_pieces=false, two_d=false,
    svm_c=None, svm_epsilon=None, svm_accuracy=None, loss="epsilon", drop_levels=0,
    model_out=None, model_in=None, svm_normal_k=None,
    rho=None, rho_geom=None, rho_topo=None, fill_holes=None, no_pockets=false,
    no_thin_parts=false, convection_normal_k=None, cover_holes=false,
    no_edge_flips=false, on_the_fly=false, no_curved_splits=false
))]
#[allow(clippy::too_many_arguments)] // the keyword arguments of the Python API
pub fn reconstruct<'py>(
    py: Python<'py>,
    points: Option<&Bound<'py, PyAny>>,
    normals: Option<&Bound<'py, PyAny>>,
    curves: Option<&Bound<'py, PyAny>>,
    triangles: Option<&Bound<'py, PyAny>>,
    method: &str,
    resolution: Option<usize>,
    report: bool,
    cancel: Option<Py<PyAny>>,
    progress: Option<Py<PyAny>>,
    epsilon: Option<f64>,
    p: Option<f64>,
    steps: Option<usize>,
    band: Option<f64>,
    levels: Option<usize>,
    bounding_box: bool,
    free_topology: bool,
    no_cleaning: bool,
    no_refine: bool,
    no_slices: bool,
    no_curve_network: bool,
    keep_pieces: bool,
    two_d: bool,
    svm_c: Option<&Bound<'py, PyAny>>,
    svm_epsilon: Option<f64>,
    svm_accuracy: Option<f64>,
    loss: &str,
    drop_levels: usize,
    model_out: Option<PathBuf>,
    model_in: Option<PathBuf>,
    svm_normal_k: Option<usize>,
    rho: Option<f64>,
    rho_geom: Option<f64>,
    rho_topo: Option<f64>,
    fill_holes: Option<usize>,
    no_pockets: bool,
    no_thin_parts: bool,
    convection_normal_k: Option<usize>,
    cover_holes: bool,
    no_edge_flips: bool,
    on_the_fly: bool,
    no_curved_splits: bool,
) -> PyResult<Bound<'py, PyTuple>> {
    let input = input_geometry(points, normals, curves, triangles)?;
    let ls = LevelSetOptions::default();
    let sv = SvmOptions::default();
    let cv = ConvectionOptions::default();
    let args = MethodArgs {
        levelset: LevelSetOptions {
            epsilon,
            p: p.unwrap_or(ls.p),
            steps: steps.unwrap_or(ls.steps),
            band: band.unwrap_or(ls.band),
            levels,
            bounding_box,
            free_topology,
            cleaning: !no_cleaning,
            refine: !no_refine,
            slices: !no_slices,
            two_d,
            field: surfrecon::FieldOutput::None,
        },
        svm: SvmOptions {
            c: parse_svm_c(svm_c)?,
            epsilon: svm_epsilon.unwrap_or(sv.epsilon),
            accuracy: svm_accuracy.unwrap_or(sv.accuracy),
            loss: self::loss(loss)?,
            drop_levels,
            model_out,
            model_in,
            normal_k: svm_normal_k.unwrap_or(sv.normal_k),
            cleaning: !no_cleaning,
        },
        convection: ConvectionOptions {
            rho: rho.unwrap_or(cv.rho),
            rho_geom: rho_geom.unwrap_or(cv.rho_geom),
            rho_topo: rho_topo.unwrap_or(cv.rho_topo),
            decimate_on_the_fly: on_the_fly,
            fill_holes: fill_holes.unwrap_or(cv.fill_holes),
            pockets: !no_pockets,
            thin_parts: !no_thin_parts,
            normal_k: convection_normal_k.unwrap_or(cv.normal_k),
            open_holes: !cover_holes,
            edge_flips: !no_edge_flips,
            split_curved_edges: !no_curved_splits,
            // The brush and the quality refinement are CLI and library
            // options only so far.
            brush: None,
            refine_alpha: cv.refine_alpha,
            refine_gamma: cv.refine_gamma,
        },
    };
    let options = Options {
        method: method_options(method, args)?,
        resolution,
        curve_network: !no_curve_network,
        join_pieces: !keep_pieces,
        data_fit: report,
    };
    let output = watched(py, cancel, progress, |hook| {
        surfrecon::reconstruct_with(&input, &options, hook)
    })?;
    let v;
    let f;
    match &output.curves {
        Some(c) => {
            v = to_vertices(py, &c.vertices).into_any();
            let segments: Vec<[u32; 2]> = c
                .lines
                .iter()
                .flat_map(|l| l.windows(2).map(|w| [w[0], w[1]]))
                .collect();
            f = to_indices(py, segments.into_iter()).into_any();
        }
        None => {
            v = to_vertices(py, &output.mesh.vertices).into_any();
            f = to_indices(py, output.mesh.triangles.iter().copied()).into_any();
        }
    }
    if report {
        let dict = json_to_py(py, &output.report)?;
        PyTuple::new(py, [v, f, dict])
    } else {
        PyTuple::new(py, [v, f])
    }
}

/// A serializable value as Python objects (through json.loads).
fn json_to_py<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// The distance field of points or a mesh on a regular 3D grid.
///
///   data        (N, 3) points, or a (vertices, faces) tuple (a mesh).
///   resolution  cells along the longest axis of the data bounds [128].
///   spacing     grid spacing instead of resolution.
///   padding     empty cells around the data bounds on every side [4].
///   signed      signed distance (negative inside) of a closed mesh.
///   allow_open  with signed: sign an open mesh by its winding number.
///   band        only compute distances within this distance of the data;
///               farther nodes hold the band value (±band when signed).
///
/// Returns (field, origin, spacing): a float64 array of shape (nx, ny, nz)
/// (field[i, j, k] at origin + spacing * (i, j, k); Fortran order, x
/// fastest, no copy), the grid origin as a tuple and the spacing.
#[pyfunction]
#[pyo3(signature = (data, *, resolution=None, spacing=None, padding=4, signed=false, allow_open=false, band=None))]
#[allow(clippy::too_many_arguments)] // the keyword arguments of the Python API
pub fn distance<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyAny>,
    resolution: Option<usize>,
    spacing: Option<f64>,
    padding: usize,
    signed: bool,
    allow_open: bool,
    band: Option<f64>,
) -> PyResult<GridField<'py>> {
    let size = match (resolution, spacing) {
        (Some(_), Some(_)) => return Err(value_error("give resolution or spacing, not both")),
        (_, Some(h)) if !(h.is_finite() && h > 0.0) => {
            return Err(value_error(format!(
                "spacing must be a positive number, not {h}"
            )))
        }
        (_, Some(h)) => GridSize::Spacing(h),
        (Some(0), None) => return Err(value_error("resolution must be at least 1")),
        (Some(n), None) => GridSize::Resolution(n),
        (None, None) => GridSize::Resolution(128),
    };
    if let Some(w) = band {
        if !(w.is_finite() && w > 0.0) {
            return Err(value_error(format!(
                "band must be a positive distance, not {w}"
            )));
        }
    }
    let shape = shape(data, "data")?;
    let field = py.detach(|| distance_field(shape, size, padding, signed, allow_open, band))?;
    grid_field(py, field)
}

/// (values with shape (nx, ny, nz), origin, spacing).
type GridField<'py> = (Bound<'py, PyArray3<f64>>, (f64, f64, f64), f64);

fn distance_field(
    shape: Shape,
    size: GridSize,
    padding: usize,
    signed: bool,
    allow_open: bool,
    band: Option<f64>,
) -> PyResult<surfrecon::Field3> {
    use surfrecon::grid::sdf::{check_closed, signed_distance};
    let grid = |e| errors::grid("distance", e);
    match shape {
        Shape::Points(_) if signed => Err(value_error(
            "signed needs a closed triangle mesh, but the data are points",
        )),
        Shape::Mesh(mesh) if signed => {
            if !allow_open {
                check_closed(&mesh).map_err(|e| {
                    errors::grid(
                        "cannot sign the mesh (allow_open=True signs it by winding number anyway)",
                        e,
                    )
                })?;
            }
            let data = DataSet::<3>::from_mesh(&mesh).map_err(grid)?;
            let spec = grid_over(&data, size, padding)?;
            signed_distance(&mesh, &spec, band).map_err(grid)
        }
        shape => {
            let geometry = match shape {
                Shape::Points(p) => Geometry::from_points(PointCloud::new(p)),
                Shape::Mesh(m) => Geometry::from_mesh(m),
            };
            let data = DataSet::<3>::from_geometry(&geometry).map_err(grid)?;
            let spec = grid_over(&data, size, padding)?;
            let options = match band {
                Some(w) => DistanceOptions {
                    band_cells: w / spec.spacing,
                    propagate: false,
                },
                None => DistanceOptions::default(),
            };
            let mut field = unsigned_distance_with(&data, &spec, &options)
                .map_err(grid)?
                .field;
            if let Some(w) = band {
                field.values.iter_mut().for_each(|v| *v = v.min(w));
            }
            Ok(field)
        }
    }
}

fn grid_over(
    data: &DataSet<3>,
    size: GridSize,
    padding: usize,
) -> PyResult<surfrecon::GridSpec<3>> {
    let Some((lo, hi)) = data.bounds() else {
        return Err(value_error("the data hold no points, lines or triangles"));
    };
    surfrecon::GridSpec::from_bounds(lo, hi, size, padding)
        .map_err(|e| errors::grid("cannot place a grid over the data", e))
}

/// The isosurface field = iso as a triangle mesh (marching cubes).
///
///   field    3D float32/float64 array, field[i, j, k] at
///            origin + spacing * (i, j, k) (any memory order).
///   origin   (x, y, z) of field[0, 0, 0].
///   spacing  distance between neighbouring nodes.
///
/// Returns (V, F): float64 (n, 3) vertices, int64 (m, 3) triangles.
#[pyfunction]
#[pyo3(signature = (field, origin, spacing, iso=0.0))]
pub fn extract<'py>(
    py: Python<'py>,
    field: &Bound<'py, PyAny>,
    origin: (f64, f64, f64),
    spacing: f64,
    iso: f64,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    if !iso.is_finite() {
        return Err(value_error(format!("iso must be finite, not {iso}")));
    }
    let field = field3(field, origin, spacing)?;
    let mesh = py.detach(|| surfrecon::grid::marching::marching_cubes(&field, iso));
    Ok((
        to_vertices(py, &mesh.vertices).into_any(),
        to_indices(py, mesh.triangles.iter().copied()).into_any(),
    ))
}

/// A 3D float array's dims and values with x fastest.
fn grid_values(field: &Bound<'_, PyAny>) -> PyResult<([usize; 3], Vec<f64>)> {
    let arr = field
        .cast::<numpy::PyUntypedArray>()
        .map_err(|_| value_error("field must be a 3D numpy array"))?;
    if arr.ndim() != 3 || arr.shape().iter().any(|&n| n < 2) {
        return Err(value_error(format!(
            "field must be a 3D array with at least 2 nodes per axis, got shape {:?}",
            arr.shape()
        )));
    }
    let dims = [arr.shape()[0], arr.shape()[1], arr.shape()[2]];
    // Iterating the transposed view visits x fastest.
    let values: Vec<f64> = if let Ok(a) = arr.cast::<PyArray3<f64>>() {
        a.readonly().as_array().t().iter().copied().collect()
    } else if let Ok(a) = arr.cast::<PyArray3<f32>>() {
        a.readonly()
            .as_array()
            .t()
            .iter()
            .map(|&v| v as f64)
            .collect()
    } else {
        return Err(value_error("field must be a float32 or float64 array"));
    };
    if values.iter().any(|v| v.is_nan()) {
        return Err(value_error("field contains NaN"));
    }
    Ok((dims, values))
}

/// Score a mesh against a reference surface, as `surfrecon eval --json`.
///
///   reference  (N, 3) points or a (vertices, faces) tuple.
///   data       (N, 3) points the mesh was built from: adds "data_fit"
///              (how closely the mesh reaches them).
///   samples    points drawn from each mesh; seed: their seed.
///
/// Returns a dict with the keys of `surfrecon eval --json`: chamfer_l1,
/// chamfer_l2, hausdorff, fscore_0_5pct, fscore_1pct, normal_consistency,
/// vertices, faces, watertight, manifold, components, euler, diagonal
/// (and data_fit).
#[pyfunction]
#[pyo3(signature = (vertices, faces, reference, *, data=None, samples=100_000, seed=0))]
pub fn evaluate<'py>(
    py: Python<'py>,
    vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
    reference: &Bound<'py, PyAny>,
    data: Option<&Bound<'py, PyAny>>,
    samples: usize,
    seed: u64,
) -> PyResult<Bound<'py, PyAny>> {
    let candidate = mesh(vertices, faces, "mesh")?;
    let reference = match shape(reference, "reference")? {
        Shape::Points(p) => Surface::Points(PointCloud::new(p)),
        Shape::Mesh(m) => Surface::Mesh(m),
    };
    let data = data.map(|d| vectors(d, "data")).transpose()?;
    let options = EvalOptions { samples, seed };
    let (scores, fit) = py.detach(|| {
        let fit = data
            .as_ref()
            .map(|d| surfrecon::geom::data_fit::data_fit(&candidate, d));
        let scores = metrics::evaluate(&Surface::Mesh(candidate.clone()), &reference, &options);
        (scores, fit)
    });
    let scores = scores
        .map_err(|e| value_error(format!("cannot compare the mesh with the reference: {e}")))?;
    let out = json_to_py(py, &scores)?;
    if let Some(fit) = fit {
        let fit = fit.map_err(|e| value_error(format!("cannot measure the data: {e}")))?;
        out.set_item("data_fit", json_to_py(py, &fit)?)?;
    }
    Ok(out)
}

/// Read a geometry file (ply, obj, off, stl, xyz; by extension).
///
/// Returns a dict: "vertices" float64 (n, 3), "normals" float64 (n, 3) or
/// None, "triangles" int64 (m, 3) (empty for point sets), "lines" a list of
/// int64 index arrays (polylines). Raises OSError naming the file, the
/// position and the problem.
#[pyfunction]
pub fn read<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let g = py
        .detach(|| surfrecon::io::read(&path))
        .map_err(errors::geom)?;
    let out = PyDict::new(py);
    out.set_item("vertices", to_vertices(py, &g.points.positions))?;
    out.set_item(
        "normals",
        g.points.normals.as_ref().map(|n| to_vertices(py, n)),
    )?;
    out.set_item("triangles", to_indices(py, g.triangles.iter().copied()))?;
    let lines: Vec<_> = g
        .lines
        .iter()
        .map(|l| {
            let l: Vec<i64> = l.iter().map(|&i| i64::from(i)).collect();
            l.into_pyarray(py)
        })
        .collect();
    out.set_item("lines", lines)?;
    Ok(out)
}

/// Write points, a mesh or polylines to a geometry file (format by
/// extension); the file is written whole or not at all.
///
///   vertices   (n, 3) float array; triangles (m, 3) integer array;
///   normals    (n, 3) per-vertex normals; lines: list of index arrays.
#[pyfunction]
#[pyo3(signature = (path, vertices, triangles=None, *, normals=None, lines=None))]
pub fn write(
    py: Python<'_>,
    path: PathBuf,
    vertices: &Bound<'_, PyAny>,
    triangles: Option<&Bound<'_, PyAny>>,
    normals: Option<&Bound<'_, PyAny>>,
    lines: Option<&Bound<'_, PyAny>>,
) -> PyResult<()> {
    let positions = vectors(vertices, "vertices")?;
    let n = positions.len();
    let mut g = Geometry::from_points(PointCloud::new(positions));
    if let Some(t) = triangles {
        g.triangles = indices::<3>(t, "triangles", n)?;
    }
    if let Some(nr) = normals {
        let nr = vectors(nr, "normals")?;
        if nr.len() != n {
            return Err(value_error(format!(
                "normals must have one row per vertex: {} normals for {n} vertices",
                nr.len()
            )));
        }
        g.points.normals = Some(nr);
    }
    if let Some(lines) = lines {
        for (i, l) in lines.try_iter()?.enumerate() {
            let l: Vec<i64> = l?.extract()?;
            if let Some(&bad) = l.iter().find(|&&x| x < 0 || x as usize >= n) {
                return Err(value_error(format!(
                    "lines[{i}] has index {bad}, outside 0..{n}"
                )));
            }
            g.lines.push(l.into_iter().map(|x| x as u32).collect());
        }
    }
    py.detach(|| surfrecon::io::write(&path, &g))
        .map_err(errors::geom)
}

/// A thin shell file (`surfrecon shell`): only the nodes next to the
/// surface of `field` (where it changes sign), from which `read_shell`
/// rebuilds the signed distance everywhere.
///
///   path     output file (the command line's shell format).
///   field    3D float32/float64 signed distance, field[i, j, k] at
///            origin + spacing * (i, j, k).
#[pyfunction]
pub fn write_shell(
    py: Python<'_>,
    path: PathBuf,
    field: &Bound<'_, PyAny>,
    origin: (f64, f64, f64),
    spacing: f64,
) -> PyResult<()> {
    let field = field3(field, origin, spacing)?;
    py.detach(|| {
        let shell = surfrecon::shell::Shell::from_field(&field);
        surfrecon::shell::write_shell(&path, &shell)
            .map_err(|e| errors::grid(&format!("cannot write shell {}", path.display()), e))
    })
}

/// The signed distance field rebuilt from a thin shell file (`surfrecon
/// unshell`): (field, origin, spacing) as `distance` returns them.
#[pyfunction]
pub fn read_shell<'py>(py: Python<'py>, path: PathBuf) -> PyResult<GridField<'py>> {
    use surfrecon::shell::AnyShell;
    let context = format!("cannot rebuild {}", path.display());
    let field = py.detach(|| match surfrecon::shell::read_shell(&path) {
        Ok(AnyShell::D3(s)) => s.rebuild().map_err(|e| errors::grid(&context, e)),
        Ok(AnyShell::D2(_)) => Err(value_error(format!(
            "{}: a 2D shell; the Python package reads 3D ones",
            path.display()
        ))),
        Err(e) => Err(errors::grid(&context, e)),
    })?;
    grid_field(py, field)
}

/// A checked 3D field from a numpy array and its grid.
fn field3(
    field: &Bound<'_, PyAny>,
    origin: (f64, f64, f64),
    spacing: f64,
) -> PyResult<surfrecon::Field3> {
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(value_error(format!(
            "spacing must be a positive number, not {spacing}"
        )));
    }
    let (dims, values) = grid_values(field)?;
    Ok(surfrecon::Field3 {
        spec: surfrecon::GridSpec {
            origin: [origin.0, origin.1, origin.2],
            spacing,
            dims,
        },
        values,
    })
}

/// A field as (array of shape (nx, ny, nz), origin, spacing), no copy.
fn grid_field(py: Python<'_>, field: surfrecon::Field3) -> PyResult<GridField<'_>> {
    let [nx, ny, nz] = field.spec.dims;
    let origin = field.spec.origin;
    let h = field.spec.spacing;
    let array = Array3::from_shape_vec((nx, ny, nz).f(), field.values)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(e.to_string()))?;
    Ok((array.into_pyarray(py), (origin[0], origin[1], origin[2]), h))
}

/// Warp a mesh onto another shape (`surfrecon morph`): SVM implicit
/// surfaces of both, and a dense warp field (feature pairs + distance
/// preservation) between them.
///
///   vertices, faces  the source mesh.
///   target           (N, 3) points or a (vertices, faces) tuple.
///   pairs            (P, 2, 3) feature correspondences: pairs[i, 0] on the
///                    source goes to pairs[i, 1] on the target.
///   c_corr=100.0     weight of the correspondences.
///   c_dist=1.0       weight of distance preservation.
///   warp_levels=4    levels of the warp field.
///   report=False     also return {"pairs", "samples", "levels"}.
///   cancel, progress as for reconstruct (checked between the fits).
///
/// Returns D, float64 (n, 3): the displacement of every source vertex;
/// frame t in [0, 1] of the morph is vertices + t * D.
#[pyfunction]
#[pyo3(signature = (vertices, faces, target, pairs=None, *, c_corr=None, c_dist=None, warp_levels=None, report=false, cancel=None, progress=None))]
#[allow(clippy::too_many_arguments)] // the keyword arguments of the Python API
pub fn morph<'py>(
    py: Python<'py>,
    vertices: &Bound<'py, PyAny>,
    faces: &Bound<'py, PyAny>,
    target: &Bound<'py, PyAny>,
    pairs: Option<&Bound<'py, PyAny>>,
    c_corr: Option<f64>,
    c_dist: Option<f64>,
    warp_levels: Option<usize>,
    report: bool,
    cancel: Option<Py<PyAny>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let source = mesh(vertices, faces, "source")?;
    let target = match shape(target, "target")? {
        Shape::Points(p) => Geometry::from_points(PointCloud::new(p)),
        Shape::Mesh(m) => Geometry::from_mesh(m),
    };
    let pairs = match pairs {
        Some(p) => feature_pairs(p)?,
        None => Vec::new(),
    };
    let d = surfrecon::MorphOptions::default();
    let options = surfrecon::MorphOptions {
        c_corr: c_corr.unwrap_or(d.c_corr),
        c_dist: c_dist.unwrap_or(d.c_dist),
        warp_levels: warp_levels.unwrap_or(d.warp_levels),
    };
    let (displacements, morph_report) = watched(py, cancel, progress, |hook| {
        let m = surfrecon::morph(&source, &target, &pairs, &options, hook)?;
        Ok((m.warp.displacements(&source.vertices), m.report))
    })?;
    let d = to_vertices(py, &displacements).into_any();
    if report {
        let r = json_to_py(py, &morph_report)?;
        Ok(PyTuple::new(py, [d, r])?.into_any())
    } else {
        Ok(d)
    }
}

/// (P, 2, 3) float array → (source point, target point) pairs.
fn feature_pairs(p: &Bound<'_, PyAny>) -> PyResult<Vec<(surfrecon::DVec3, surfrecon::DVec3)>> {
    let arr = p
        .cast::<numpy::PyUntypedArray>()
        .map_err(|_| value_error("pairs must be a numpy array of shape (P, 2, 3)"))?;
    if arr.ndim() != 3 || arr.shape()[1] != 2 || arr.shape()[2] != 3 {
        return Err(value_error(format!(
            "pairs must have shape (P, 2, 3), got {:?}",
            arr.shape()
        )));
    }
    let flat = arr.call_method1("reshape", ((-1i64, 3i64),))?;
    let points = vectors(&flat, "pairs")?;
    Ok(points.chunks(2).map(|c| (c[0], c[1])).collect())
}
