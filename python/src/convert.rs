//! Library values to Python objects: what the command line writes as JSON becomes the same
//! dict (through `json.loads`, so keys, order and nulls are exactly the files').

use pyo3::prelude::*;
use serde::Serialize;

/// `value` as the Python object of its JSON form.
pub fn json<'py, T: Serialize>(py: Python<'py>, value: &T) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value)
        .map_err(|e| crate::errors::setting("json", format!("cannot be serialised: {e}")))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A TOML value from a Python keyword value (bool, int, float, str, or a list of these).
pub fn toml_value(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<toml::Value> {
    use pyo3::types::{PyBool, PyFloat, PyInt, PyList, PyString, PyTuple};
    if obj.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(obj.extract()?));
    }
    if obj.is_instance_of::<PyInt>() {
        return Ok(toml::Value::Integer(obj.extract()?));
    }
    if obj.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(obj.extract()?));
    }
    if obj.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(obj.extract()?));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() || obj.hasattr("tolist")? {
        let list = if obj.hasattr("tolist")? { obj.call_method0("tolist")? } else { obj.clone() };
        let mut out = Vec::new();
        for item in list.try_iter()? {
            out.push(toml_value(&item?, name)?);
        }
        return Ok(toml::Value::Array(out));
    }
    Err(crate::errors::setting(name, format!("must be a bool, number, string or list, got {}", obj.get_type().name()?)))
}
