//! `nmci._nmci`: the Python extension module, a thin layer over nmci's Rust API.
//!
//! The Python package `nmci` (python/nmci/__init__.py) wraps these functions with documented
//! signatures. Here:
//! - matrices cross as numpy `float64` (and `bool` patterns) and go out as numpy arrays;
//! - options cross as Python objects, read by serde straight into the Rust types
//!   ([`nmci::contract::Options`], [`nmci::study::StudyConfig`]) through `pythonize`, so every
//!   default, check and message is the Rust one and an error names its field from serde's own
//!   path (`serde_path_to_error`), never from its message;
//! - results go out as Python objects written by serde from the Rust values: a fusion response
//!   is [`fuse::Fused`], whose attributes are the contract's fields
//!   ([`nmci::contract::response_fields`]);
//! - every solve, sample and study runs with the GIL released ([`Python::detach`]) and inside
//!   `catch_unwind`, so Python threads run in parallel and a Rust panic surfaces as
//!   `nmci.InternalError` instead of a crash;
//! - studies and fig. 2 run on a rayon pool built per call, never rayon's global pool, so they
//!   also run in processes forked from one that used nmci (Python's process pools on Linux);
//! - errors become the exceptions of `nmci._errors` (one class per Rust error concern), with
//!   the request field at fault as their `field`;
//! - Rust's allocations go to mimalloc (as polars' Python package does): a single small fusion
//!   makes some fifty short-lived allocations (the matrices of the problem, the pencil and the
//!   response), and glibc's allocator was about a tenth of such a call (`perf`); memory handed
//!   to numpy (`PyArray1::from_vec`) is freed by Rust, through the same allocator.

use std::panic::{catch_unwind, AssertUnwindSafe};

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyList, PyTuple};
use serde::de::DeserializeOwned;
use serde::Serialize;

use nmci::{RequestError, SampleError, SolveError};

mod fuse;
mod study;

#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// The exception of `nmci._errors` named `kind`, carrying `message`.
fn error(py: Python<'_>, kind: &str, message: String) -> PyErr {
    error_at(py, kind, message, None)
}

/// The exception of `nmci._errors` named `kind`, carrying `message` and the request `field` at
/// fault (its `field` attribute; `None` when no single field is).
fn error_at(py: Python<'_>, kind: &str, message: String, field: Option<String>) -> PyErr {
    let class = match py.import("nmci._errors").and_then(|m| m.getattr(kind)) {
        Ok(class) => class,
        Err(e) => return e,
    };
    match class.call1((message, field)) {
        Ok(value) => PyErr::from_value(value),
        Err(e) => e,
    }
}

/// The exception class of a request's error.
fn request_error_kind(e: &RequestError) -> &'static str {
    match e {
        RequestError::Malformed(_)
        | RequestError::Invalid { .. }
        | RequestError::TooLarge { .. } => "RequestError",
        RequestError::Input(_) => "InputError",
        RequestError::Sample(SampleError::InvalidSettings(_)) => "RequestError",
        RequestError::Sample(_) => "SampleError",
        RequestError::InStack { source, .. } | RequestError::InList { source, .. } => {
            request_error_kind(source)
        }
        RequestError::Solve(e) => match e {
            SolveError::TimeLimit { .. } => "TimeLimitError",
            SolveError::InvalidSettings(_) => "RequestError",
            SolveError::Input(_) => "InputError",
            SolveError::Sample(SampleError::InvalidSettings(_)) => "RequestError",
            SolveError::Sample(_) => "SampleError",
            _ => "SolveError",
        },
    }
}

fn request_error(py: Python<'_>, e: RequestError) -> PyErr {
    error_at(py, request_error_kind(&e), e.to_string(), e.field())
}

/// `value` read by serde as a `T`, or a `RequestError` naming the field at fault: `field`
/// when given (the value is that field's), else the first step of serde's path (the value is
/// a dict of fields). The message gives the whole path (`` `blocks[1][0]`: … ``).
///
/// No option of the contract is a boolean, but Python's `True` is also the integer 1: a bool
/// given for a field is refused here rather than read as a count or a seed.
fn contract_value<T: DeserializeOwned>(
    py: Python<'_>,
    value: &Bound<'_, PyAny>,
    field: Option<&str>,
) -> PyResult<T> {
    let refuse = |field: &str, at: &str, message: String| {
        request_error(
            py,
            RequestError::invalid(field, format!("`{at}`: {message}")),
        )
    };
    let fields: Vec<(String, Bound<'_, PyAny>)> = match (field, value.cast::<PyDict>()) {
        (Some(field), _) => vec![(field.to_owned(), value.clone())],
        (None, Ok(dict)) => dict
            .iter()
            .map(|(k, v)| Ok((k.extract::<String>()?, v)))
            .collect::<PyResult<_>>()?,
        (None, Err(_)) => Vec::new(),
    };
    if let Some((name, _)) = fields.iter().find(|(_, v)| v.is_instance_of::<PyBool>()) {
        return Err(refuse(
            name,
            name,
            "a boolean is not a value of this field".into(),
        ));
    }
    let mut de = pythonize::Depythonizer::from_object(value);
    serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let path = e.path().to_string();
        let at = match (field, path.as_str()) {
            (Some(field), ".") => field.to_owned(),
            (Some(field), p) if p.starts_with('[') => format!("{field}{p}"),
            (Some(field), p) => format!("{field}.{p}"),
            (None, p) => p.to_owned(),
        };
        let name = field.unwrap_or_else(|| at.split(['.', '[']).next().unwrap_or(&at));
        refuse(name, &at, e.into_inner().to_string())
    })
}

/// A Rust value as Python objects, as serde writes it: structs and maps as dicts, sequences
/// (tuples and fixed arrays too, as JSON has them) as lists.
fn to_python<'py, T: Serialize>(py: Python<'py>, value: &T) -> PyResult<Bound<'py, PyAny>> {
    let object =
        pythonize::pythonize(py, value).map_err(|e| error(py, "InternalError", e.to_string()))?;
    lists(object)
}

/// `object` with every tuple (serde's form of a pair or a fixed array) made a list.
fn lists(object: Bound<'_, PyAny>) -> PyResult<Bound<'_, PyAny>> {
    let py = object.py();
    if let Ok(dict) = object.cast::<PyDict>() {
        for (key, value) in dict.iter() {
            dict.set_item(key, lists(value)?)?;
        }
        Ok(object)
    } else if let Ok(list) = object.cast::<PyList>() {
        for i in 0..list.len() {
            list.set_item(i, lists(list.get_item(i)?)?)?;
        }
        Ok(object)
    } else if let Ok(tuple) = object.cast::<PyTuple>() {
        let items = tuple.iter().map(lists).collect::<PyResult<Vec<_>>>()?;
        Ok(PyList::new(py, items)?.into_any())
    } else {
        Ok(object)
    }
}

/// Runs `work` without the GIL; a panic becomes `nmci.InternalError`.
fn detached<T: Send>(py: Python<'_>, work: impl FnOnce() -> T + Send) -> PyResult<T> {
    py.detach(|| catch_unwind(AssertUnwindSafe(work)))
        .map_err(|panic| {
            let message = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            error(
                py,
                "InternalError",
                format!("nmci panicked (a bug: please report it): {message}"),
            )
        })
}

/// Runs `work` as [`detached`] does, on a rayon pool built for this call (every core, or
/// `RAYON_NUM_THREADS`): rayon's global pool does not survive `fork`, and Python's process pools
/// fork on Linux — a worker process calling a study would wait forever for the parent's threads.
fn parallel<T: Send>(py: Python<'_>, work: impl FnOnce() -> T + Send) -> PyResult<T> {
    detached(py, || {
        rayon::ThreadPoolBuilder::new()
            .build()
            .map(|pool| pool.install(work))
            .map_err(|e| e.to_string())
    })?
    .map_err(|e| {
        error(
            py,
            "InternalError",
            format!("cannot start a thread pool: {e}"),
        )
    })
}

/// The registry of rules ([`nmci::rules::RULES`]), a dict per rule.
#[pyfunction]
fn rules(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_python(py, &nmci::rules::RULES)
}

/// The JSON request field of an input named in an error (`P_a` → `pa`; [`nmci::request_field`]).
#[pyfunction]
fn request_field(name: &str) -> String {
    nmci::request_field(name)
}

/// Panics inside a detached solve: the tests check it arrives as `nmci.InternalError`.
#[pyfunction]
fn _panic_for_test(py: Python<'_>) -> PyResult<()> {
    detached(py, || panic!("a panic raised on purpose by the tests"))
}

#[pymodule]
fn _nmci(m: &Bound<'_, PyModule>) -> PyResult<()> {
    fuse::register(m)?;
    study::register(m)?;
    m.add_function(wrap_pyfunction!(rules, m)?)?;
    m.add_function(wrap_pyfunction!(request_field, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_test, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
