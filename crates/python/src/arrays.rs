//! numpy arrays and cvtrace images: any array-like in (made float32 and C-contiguous by numpy,
//! then copied), (H, W, C) float32 arrays out, either owning a buffer moved from Rust or
//! read-only views of an image a Python object keeps alive.
use cvtrace_streams::Image;
use numpy::ndarray::{ArrayView, Dimension, IntoDimension};
use numpy::{PyArray, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// `value` as a float32, C-contiguous numpy array (a copy only where numpy needs one), so that
/// lists, other dtypes, Fortran-ordered arrays and anything with `__array__` are accepted.
pub fn float32<'py>(py: Python<'py>, value: &Bound<'py, PyAny>, what: &str) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let numpy = py.import("numpy")?;
    let float32 = numpy.getattr("float32")?;
    let array = numpy.call_method1("ascontiguousarray", (value, float32)).map_err(|e| {
        let message = format!("{what}: not an array of numbers ({})", e.value(py));
        let error = PyErr::new::<pyo3::exceptions::PyTypeError, _>(message);
        error.set_cause(py, Some(e));
        error
    })?;
    Ok(array.cast_into::<PyArrayDyn<f32>>()?)
}

/// The shape of `array` in words, `(4, 8, 3)`.
fn shape_text(shape: &[usize]) -> String {
    match shape {
        [one] => format!("({one},)"),
        _ => format!("({})", shape.iter().map(usize::to_string).collect::<Vec<_>>().join(", ")),
    }
}

/// An (H, W, 3) array-like as an image; `what` names the argument in errors.
pub fn image(py: Python<'_>, value: &Bound<'_, PyAny>, what: &str) -> PyResult<Image> {
    let array = float32(py, value, what)?;
    let shape = array.shape().to_vec();
    let [h, w, 3] = shape[..] else {
        return Err(PyValueError::new_err(format!("{what}: expected an array of shape (H, W, 3), got {}", shape_text(&shape))));
    };
    nonempty(what, w, h)?;
    let readonly = array.readonly();
    let flat = readonly.as_slice()?;
    Ok(Image { width: w, height: h, pixels: flat.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect() })
}

/// A (B, H, W, 3) array-like (or a sequence of (H, W, 3) ones) as `B` images.
pub fn images(py: Python<'_>, value: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<Image>> {
    let array = float32(py, value, what)?;
    let shape = array.shape().to_vec();
    let [b, h, w, 3] = shape[..] else {
        return Err(PyValueError::new_err(format!("{what}: expected an array of shape (B, H, W, 3), got {}", shape_text(&shape))));
    };
    if b == 0 {
        return Err(PyValueError::new_err(format!("{what}: no batches (shape {})", shape_text(&shape))));
    }
    nonempty(what, w, h)?;
    let readonly = array.readonly();
    let flat = readonly.as_slice()?;
    Ok(flat
        .chunks_exact(w * h * 3)
        .map(|batch| Image { width: w, height: h, pixels: batch.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect() })
        .collect())
}

/// An (H, W) array-like as a row-major plane.
pub fn plane(py: Python<'_>, value: &Bound<'_, PyAny>, what: &str) -> PyResult<(usize, usize, Vec<f32>)> {
    let array = float32(py, value, what)?;
    let shape = array.shape().to_vec();
    let [h, w] = shape[..] else {
        return Err(PyValueError::new_err(format!("{what}: expected an array of shape (H, W), got {}", shape_text(&shape))));
    };
    nonempty(what, w, h)?;
    Ok((w, h, array.readonly().as_slice()?.to_vec()))
}

fn nonempty(what: &str, w: usize, h: usize) -> PyResult<()> {
    if w == 0 || h == 0 {
        return Err(PyValueError::new_err(format!("{what}: the image is empty ({w}x{h})")));
    }
    Ok(())
}

/// `image` as a new (H, W, 3) float32 array that owns its pixels (moved, not copied).
pub fn to_numpy(py: Python<'_>, image: Image) -> PyResult<Bound<'_, PyAny>> {
    let (w, h) = (image.width, image.height);
    Ok(PyArray::from_vec(py, image.pixels.into_flattened()).reshape([h, w, 3])?.into_any())
}

/// A row-major plane as a new (H, W) float32 array.
pub fn plane_to_numpy(py: Python<'_>, width: usize, height: usize, values: Vec<f32>) -> PyResult<Bound<'_, PyAny>> {
    Ok(PyArray::from_vec(py, values).reshape([height, width])?.into_any())
}

/// A read-only array of shape `shape` over `data`, which `owner` keeps alive and unchanged.
///
/// The caller vouches that `owner` owns `data` and never changes or frees it while `owner`
/// lives: the array keeps `owner` alive, so a view can never outlive the pixels it shows.
pub fn view<'py, D: IntoDimension>(owner: Bound<'py, PyAny>, shape: D, data: &[f32]) -> PyResult<Bound<'py, PyAny>>
where
    D::Dim: Dimension,
{
    let view = ArrayView::from_shape(shape, data).map_err(|e| PyValueError::new_err(format!("an image of the wrong size: {e}")))?;
    #[allow(unsafe_code)]
    // SAFETY: `owner` (a frozen `Streams`) holds the `Arc` that owns `data` and never changes
    // or frees it; the array holds a reference to `owner`, so `data` outlives the array. The
    // array is made read-only at once, so numpy never writes through it.
    let array = unsafe { PyArray::<f32, D::Dim>::borrow_from_array(&view, owner) };
    array.getattr("flags")?.setattr("writeable", false)?;
    Ok(array.into_any())
}
