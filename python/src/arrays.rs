//! NumPy in and out: points of an n-joint arm as (N, n) blocks (or one point as (n,)), checked
//! for shape and finiteness before any library call, so a bad array is a `springfit.SettingError`
//! naming the argument and never a crash.

use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::setting;

/// Rows of n numbers read from an array argument.
pub struct Points {
    /// Row-major, `count × n`.
    pub data: Vec<f64>,
    /// Number of rows.
    pub count: usize,
    /// The argument was one point (shape (n,)): results drop the leading axis.
    pub single: bool,
    /// Numbers per row.
    pub n: usize,
}

impl Points {
    /// Row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.data[i * self.n..(i + 1) * self.n]
    }
}

/// A float64 view of `obj` (an ndarray as it is, anything else through `numpy.asarray`).
fn float_array<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    if let Ok(a) = obj.extract::<PyReadonlyArrayDyn<'py, f64>>() {
        return Ok(a);
    }
    let py = obj.py();
    let np = py.import("numpy")?;
    let converted = np
        .call_method1("asarray", (obj, "float64"))
        .map_err(|e| setting(name, format!("must be an array of numbers ({e})")))?;
    converted
        .extract::<PyReadonlyArrayDyn<'py, f64>>()
        .map_err(|e| setting(name, format!("must be an array of numbers ({e})")))
}

/// Reads `obj` as points of `n` numbers: shape (n,) or (N, n), every entry finite.
pub fn points(obj: &Bound<'_, PyAny>, n: usize, name: &str) -> PyResult<Points> {
    let a = float_array(obj, name)?;
    let shape = a.shape().to_vec();
    let (count, single) = match shape[..] {
        [k] if k == n => (1, true),
        [count, k] if k == n => (count, false),
        _ => {
            let got = shape.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", ");
            let got = if shape.len() == 1 { format!("({got},)") } else { format!("({got})") };
            return Err(setting(
                name,
                format!("must have shape ({n},) or (N, {n}) for the robot's {n} joints, got {got}"),
            ));
        }
    };
    let data: Vec<f64> = match a.as_slice() {
        Ok(s) => s.to_vec(),
        Err(_) => a.as_array().iter().copied().collect(),
    };
    if let Some(k) = data.iter().position(|x| !x.is_finite()) {
        let at = if single { format!("{name}[{k}]") } else { format!("{name}[{}, {}]", k / n, k % n) };
        return Err(setting(at, format!("must be finite, got {}", data[k])));
    }
    Ok(Points { data, count, single, n })
}

/// One vector of `n` numbers (shape (n,)), finite.
pub fn vector(obj: &Bound<'_, PyAny>, n: usize, name: &str) -> PyResult<Vec<f64>> {
    let p = points(obj, n, name)?;
    if !p.single {
        return Err(setting(name, format!("must be one vector of shape ({n},), got {} rows", p.count)));
    }
    Ok(p.data)
}

/// An array of shape `lead + tail` from row-major data, where `lead` is (N,) or () for one point.
pub fn shaped<'py>(
    py: Python<'py>,
    data: Vec<f64>,
    single: bool,
    count: usize,
    tail: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let mut shape: Vec<usize> = if single { Vec::new() } else { vec![count] };
    shape.extend_from_slice(tail);
    PyArray1::from_vec(py, data).reshape(shape)
}
