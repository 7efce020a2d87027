//! numpy arrays to the facade's types and back. Inputs: float32 or float64
//! (N, 3) arrays in any memory order (read through their strides, one pass
//! into the f64 vectors the methods work on); integer (M, 3) faces.
//! Outputs: float64 (N, 3) vertices and int64 faces.

use crate::errors::value_error;
use numpy::ndarray::{Array2, ArrayView2};
use numpy::{
    IntoPyArray, PyArray2, PyArrayDescrMethods, PyArrayMethods, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use surfrecon::DVec3;

/// A numpy array or a ValueError naming `name`.
fn array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Bound<'py, PyUntypedArray>> {
    obj.cast::<PyUntypedArray>().cloned().map_err(|_| {
        value_error(format!(
            "{name} must be a numpy array, got {}",
            obj.get_type().name().map_or("?".into(), |n| n.to_string())
        ))
    })
}

fn shape_text(shape: &[usize]) -> String {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    }
}

/// The rows of a float32/float64 (N, 3) array, checked finite and non-empty.
pub fn vectors(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<DVec3>> {
    let arr = array(obj, name)?;
    if arr.ndim() != 2 || arr.shape()[1] != 3 {
        return Err(value_error(format!(
            "{name} must have shape (N, 3), got {}",
            shape_text(arr.shape())
        )));
    }
    if arr.shape()[0] == 0 {
        return Err(value_error(format!("{name} is empty (shape (0, 3))")));
    }
    let rows = float_rows::<3>(&arr, name)?;
    let rows: Vec<DVec3> = rows.into_iter().map(DVec3::from_array).collect();
    if let Some(i) = rows.iter().position(|v| !v.is_finite()) {
        return Err(value_error(format!(
            "{name} row {i} is not finite: {}",
            rows[i]
        )));
    }
    Ok(rows)
}

/// Rows of `D` floats of a 2D float32/float64 array of `D` columns.
fn float_rows<const D: usize>(
    arr: &Bound<'_, PyUntypedArray>,
    name: &str,
) -> PyResult<Vec<[f64; D]>> {
    let collect = |view: ArrayView2<'_, f64>| -> Vec<[f64; D]> {
        view.rows()
            .into_iter()
            .map(|r| std::array::from_fn(|a| r[a]))
            .collect()
    };
    if let Ok(a) = arr.cast::<PyArray2<f64>>() {
        return Ok(collect(a.readonly().as_array()));
    }
    if let Ok(a) = arr.cast::<PyArray2<f32>>() {
        let ro = a.readonly();
        return Ok(ro
            .as_array()
            .rows()
            .into_iter()
            .map(|r| std::array::from_fn(|c| r[c] as f64))
            .collect());
    }
    Err(value_error(format!(
        "{name} must be a float32 or float64 array, got dtype {}",
        arr.dtype().str().map_or("?".into(), |s| s.to_string())
    )))
}

/// The rows of an integer (M, K) index array, each below `bound`.
pub fn indices<const K: usize>(
    obj: &Bound<'_, PyAny>,
    name: &str,
    bound: usize,
) -> PyResult<Vec<[u32; K]>> {
    let arr = array(obj, name)?;
    if arr.ndim() != 2 || arr.shape()[1] != K {
        return Err(value_error(format!(
            "{name} must have shape (M, {K}), got {}",
            shape_text(arr.shape())
        )));
    }
    let kind = arr.dtype().kind();
    if kind != b'i' && kind != b'u' {
        return Err(value_error(format!(
            "{name} must be an integer array, got dtype {}",
            arr.dtype().str().map_or("?".into(), |s| s.to_string())
        )));
    }
    let as_i64 = arr.call_method1("astype", ("int64",))?;
    let a = as_i64
        .cast::<PyArray2<i64>>()
        .map_err(|_| value_error(format!("{name}: cannot read as int64")))?;
    let ro = a.readonly();
    let mut rows = Vec::with_capacity(arr.shape()[0]);
    for (i, r) in ro.as_array().rows().into_iter().enumerate() {
        if let Some(&bad) = r.iter().find(|&&x| x < 0 || x as u64 >= bound as u64) {
            return Err(value_error(format!(
                "{name} row {i} has index {bad}, outside 0..{bound}"
            )));
        }
        rows.push(std::array::from_fn(|c| r[c] as u32));
    }
    Ok(rows)
}

/// float64 (N, 3).
pub fn to_vertices<'py>(py: Python<'py>, v: &[DVec3]) -> Bound<'py, PyArray2<f64>> {
    let flat: Vec<f64> = v.iter().flat_map(|p| p.to_array()).collect();
    Array2::from_shape_vec((v.len(), 3), flat)
        .expect("3 per row")
        .into_pyarray(py)
}

/// int64 (M, K).
pub fn to_indices<'py, const K: usize>(
    py: Python<'py>,
    rows: impl ExactSizeIterator<Item = [u32; K]>,
) -> Bound<'py, PyArray2<i64>> {
    let n = rows.len();
    let flat: Vec<i64> = rows.flat_map(|r| r.map(i64::from)).collect();
    Array2::from_shape_vec((n, K), flat)
        .expect("K per row")
        .into_pyarray(py)
}
