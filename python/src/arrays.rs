//! numpy arrays in and out, with their shapes and values checked: a wrong shape or a
//! non-finite entry raises `ValueError` naming the argument.

use numpy::{PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

fn shape_text(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// `obj` as a float64 array of exactly `shape`, its entries finite, row-major into `out`.
pub(crate) fn read_into(
    obj: &Bound<'_, PyAny>,
    name: &str,
    shape: &[usize],
    out: &mut [f64],
) -> PyResult<()> {
    // a float64 array is read as it is; anything else (a list, an int array) through
    // numpy.asarray, whose own error for a ragged list is a ValueError too
    let converted;
    let array: PyReadonlyArrayDyn<'_, f64> = match obj.extract() {
        Ok(a) => a,
        Err(_) => {
            let np = PyModule::import(obj.py(), "numpy")?;
            converted = np.call_method1("asarray", (obj, "float64")).map_err(|e| {
                PyValueError::new_err(format!("{name}: not an array of numbers ({e})"))
            })?;
            converted
                .cast::<PyArrayDyn<f64>>()
                .map_err(|_| PyValueError::new_err(format!("{name}: not an array of numbers")))?
                .readonly()
        }
    };
    if array.shape() != shape {
        return Err(PyValueError::new_err(format!(
            "{name}: expected shape {}, got {}",
            shape_text(shape),
            shape_text(array.shape())
        )));
    }
    let view = array.as_array();
    for (i, (o, x)) in out.iter_mut().zip(view.iter()).enumerate() {
        if !x.is_finite() {
            return Err(PyValueError::new_err(format!(
                "{name}: entry {i} is {x}, not a finite number"
            )));
        }
        *o = *x;
    }
    Ok(())
}

/// `obj` as a vector of `N` finite floats.
pub(crate) fn vector<const N: usize>(
    obj: &Bound<'_, PyAny>,
    name: &str,
) -> PyResult<nalgebra::SVector<f64, N>> {
    let mut v = [0.0; N];
    read_into(obj, name, &[N], &mut v)?;
    Ok(nalgebra::SVector::from(v))
}

/// `obj` as an `R × C` matrix of finite floats (given row-major, as numpy prints it).
pub(crate) fn matrix<const R: usize, const C: usize>(
    obj: &Bound<'_, PyAny>,
    name: &str,
) -> PyResult<nalgebra::SMatrix<f64, R, C>> {
    let mut v = vec![0.0; R * C];
    read_into(obj, name, &[R, C], &mut v)?;
    Ok(nalgebra::SMatrix::from_row_slice(&v))
}

/// `obj` as `k` rows of 3 (directions), `k` given by the array.
pub(crate) fn rows3(
    obj: &Bound<'_, PyAny>,
    name: &str,
    k: usize,
) -> PyResult<Vec<nalgebra::Vector3<f64>>> {
    let mut v = vec![0.0; 3 * k];
    read_into(obj, name, &[k, 3], &mut v)?;
    Ok(v.chunks(3).map(nalgebra::Vector3::from_row_slice).collect())
}

/// The first dimension of an array-like (its number of rows), or a `ValueError`.
pub(crate) fn rows(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<usize> {
    obj.len()
        .map_err(|_| PyValueError::new_err(format!("{name}: expected a sequence of rows")))
}

/// A 1-D float64 array.
pub(crate) fn out1<'py>(py: Python<'py>, xs: &[f64]) -> Bound<'py, numpy::PyArray1<f64>> {
    numpy::PyArray1::from_slice(py, xs)
}

/// A 2-D float64 array from a matrix (row-major, as numpy holds it).
pub(crate) fn out2<'py, const R: usize, const C: usize>(
    py: Python<'py>,
    m: &nalgebra::SMatrix<f64, R, C>,
) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
    let rows: Vec<Vec<f64>> = (0..R)
        .map(|i| (0..C).map(|j| m[(i, j)]).collect())
        .collect();
    numpy::PyArray2::from_vec2(py, &rows).map_err(|e| PyValueError::new_err(e.to_string()))
}
