//! Values across the boundary: state vectors in (float64 numpy arrays read in place, or
//! lists of numbers), JSON reports out as dicts of numpy arrays, dicts in as TOML.

use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use serde_json::Value;

/// A vector argument: a float64 numpy array borrowed without a copy when it is
/// contiguous, else the numbers copied out.
pub enum Vector<'py> {
    Borrowed(PyReadonlyArray1<'py, f64>),
    Owned(Vec<f64>),
}

impl Vector<'_> {
    pub fn as_slice(&self) -> &[f64] {
        match self {
            // `vector` only keeps contiguous arrays borrowed.
            Vector::Borrowed(array) => array.as_slice().unwrap_or(&[]),
            Vector::Owned(values) => values,
        }
    }
}

/// Reads argument `name` as `n` float64 numbers: a 1-D float64 numpy array of length `n`
/// (read in place when contiguous), or a sequence of `n` Python numbers. Another dtype, a
/// shape other than `(n,)` or a non-number is a `TypeError`/`ValueError` naming `name`.
pub fn vector<'py>(value: &Bound<'py, PyAny>, name: &str, n: usize) -> PyResult<Vector<'py>> {
    if let Ok(array) = value.cast::<numpy::PyUntypedArray>() {
        let dtype = array.dtype();
        let shape = array.shape().to_vec();
        if shape != [n] {
            return Err(PyValueError::new_err(format!(
                "{name}: expected shape ({n},), got {shape:?}"
            )));
        }
        let Ok(typed) = value.cast::<PyArray1<f64>>() else {
            return Err(PyTypeError::new_err(format!(
                "{name}: expected a float64 array, got dtype {dtype}; convert with \
                 numpy.asarray({name}, dtype=float)"
            )));
        };
        let read = typed.readonly();
        return Ok(if read.as_slice().is_ok() {
            Vector::Borrowed(read)
        } else {
            Vector::Owned(read.as_array().to_vec())
        });
    }
    if value.is_instance_of::<PyString>() {
        return Err(PyTypeError::new_err(format!(
            "{name}: expected {n} numbers, got a string"
        )));
    }
    let values: Vec<f64> = value.extract().map_err(|_| {
        PyTypeError::new_err(format!(
            "{name}: expected a float64 numpy array or a sequence of {n} numbers, got {}",
            type_name(value)
        ))
    })?;
    if values.len() != n {
        return Err(PyValueError::new_err(format!(
            "{name}: expected {n} values, got {}",
            values.len()
        )));
    }
    Ok(Vector::Owned(values))
}

/// A vector argument that must also be finite (`ValueError` naming the first bad entry).
pub fn finite_vector<'py>(
    value: &Bound<'py, PyAny>,
    name: &str,
    n: usize,
) -> PyResult<Vector<'py>> {
    let vector = vector(value, name, n)?;
    if let Some(k) = vector.as_slice().iter().position(|v| !v.is_finite()) {
        return Err(PyValueError::new_err(format!(
            "{name}: entry {k} is {}; values must be finite",
            vector.as_slice()[k]
        )));
    }
    Ok(vector)
}

fn type_name(value: &Bound<'_, PyAny>) -> String {
    value
        .get_type()
        .name()
        .map_or_else(|_| "an object".to_string(), |n| n.to_string())
}

/// The shape of `value` if it is a rectangular nest of arrays of (floating) numbers.
fn numeric_shape(value: &Value) -> Option<Vec<usize>> {
    match value {
        Value::Number(number) if number.is_f64() => Some(Vec::new()),
        Value::Array(items) if !items.is_empty() => {
            let inner = numeric_shape(&items[0])?;
            for item in &items[1..] {
                if numeric_shape(item)? != inner {
                    return None;
                }
            }
            let mut shape = vec![items.len()];
            shape.extend(inner);
            Some(shape)
        }
        _ => None,
    }
}

fn flatten(value: &Value, out: &mut Vec<f64>) {
    match value {
        Value::Number(number) => out.push(number.as_f64().unwrap_or(f64::NAN)),
        Value::Array(items) => items.iter().for_each(|item| flatten(item, out)),
        _ => {}
    }
}

/// A JSON report as Python objects: every array of floats (nested rectangularly, any
/// depth) becomes a float64 numpy array of that shape, objects become dicts, the rest
/// lists, strings, numbers, booleans and None.
pub fn json_to_python<'py>(py: Python<'py>, value: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(number) => {
            if let Some(i) = number.as_i64().filter(|_| !number.is_f64()) {
                i.into_pyobject(py)?.into_any()
            } else if let Some(u) = number.as_u64().filter(|_| !number.is_f64()) {
                u.into_pyobject(py)?.into_any()
            } else {
                PyFloat::new(py, number.as_f64().unwrap_or(f64::NAN)).into_any()
            }
        }
        Value::String(text) => PyString::new(py, text).into_any(),
        Value::Array(items) => match numeric_shape(value) {
            Some(shape) => {
                let mut flat = Vec::new();
                flatten(value, &mut flat);
                let array = PyArray1::from_vec(py, flat);
                let shaped: Bound<'py, PyArrayDyn<f64>> = array.reshape(shape)?;
                shaped.into_any()
            }
            None => {
                let list = PyList::empty(py);
                for item in items {
                    list.append(json_to_python(py, item)?)?;
                }
                list.into_any()
            }
        },
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (key, item) in map {
                dict.set_item(key, json_to_python(py, item)?)?;
            }
            dict.into_any()
        }
    })
}

/// A Python dict (of dicts, lists, tuples, numpy arrays, strings, numbers and booleans) as
/// TOML text, for a scenario given as a dict. `where_` names the value in errors.
pub fn dict_to_toml(value: &Bound<'_, PyDict>) -> PyResult<String> {
    let table = to_table(value, "scenario")?;
    toml::to_string(&table).map_err(|e| {
        PyValueError::new_err(format!("scenario dict: cannot be written as TOML: {e}"))
    })
}

fn to_table(dict: &Bound<'_, PyDict>, where_: &str) -> PyResult<toml::Table> {
    let mut table = toml::Table::new();
    for (key, item) in dict.iter() {
        let key: String = key.extract().map_err(|_| {
            PyTypeError::new_err(format!(
                "{where_}: keys must be strings, got {}",
                type_name(&key)
            ))
        })?;
        let inner = format!("{where_}[{key:?}]");
        if item.is_none() {
            continue;
        }
        table.insert(key, to_toml(&item, &inner)?);
    }
    Ok(table)
}

fn to_toml(value: &Bound<'_, PyAny>, where_: &str) -> PyResult<toml::Value> {
    if let Ok(dict) = value.cast::<PyDict>() {
        return Ok(toml::Value::Table(to_table(dict, where_)?));
    }
    if value.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(value.extract()?));
    }
    if value.is_instance_of::<PyInt>() {
        let integer: i64 = value
            .extract()
            .map_err(|_| PyValueError::new_err(format!("{where_}: integer out of range")))?;
        return Ok(toml::Value::Integer(integer));
    }
    if let Ok(number) = value.extract::<f64>()
        && !value.is_instance_of::<PyString>()
        && !value.hasattr("tolist")?
    {
        return Ok(toml::Value::Float(number));
    }
    if let Ok(text) = value.cast::<PyString>() {
        return Ok(toml::Value::String(text.to_cow()?.into_owned()));
    }
    // numpy arrays and scalars, as Python lists and numbers.
    if value.hasattr("tolist")? {
        return to_toml(&value.call_method0("tolist")?, where_);
    }
    if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        let mut items = Vec::new();
        for (k, item) in value.try_iter()?.enumerate() {
            items.push(to_toml(&item?, &format!("{where_}[{k}]"))?);
        }
        return Ok(toml::Value::Array(items));
    }
    Err(PyTypeError::new_err(format!(
        "{where_}: a scenario holds tables, lists, strings, numbers and booleans, got {}",
        type_name(value)
    )))
}
