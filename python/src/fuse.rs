//! Fusion: the contract's rules with numpy arrays ([`fuse_arrays`]) and its JSON text
//! ([`fuse_json`]), the result type [`Fused`], and the tools (conservativeness index, sampled
//! cross-covariances).

use numpy::{
    PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2,
    PyReadonlyArray3, PyUntypedArrayMethods,
};
use std::sync::{Arc, Mutex};

use pyo3::exceptions::{PyAttributeError, PyKeyError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

use nmci::contract::{
    field_names, fuse_stack as stack, response_fields, Details, FuseRequest, FuseResponse, Gains,
    NwayEstimate, NwayPair, Options, PairInput, StackRequest,
};
use nmci::rules::Method;
use nmci::RequestError;

use crate::{contract_value, detached, error, error_at, request_error, to_python};

/// `a`'s rows, copied under the GIL without registering a borrow (`to_owned_array`, safe: a
/// copy taken while no Python code runs); numpy's borrow bookkeeping was a measurable part of
/// a single call.
fn rows(a: &Bound<'_, PyArray2<f64>>) -> Vec<Vec<f64>> {
    a.to_owned_array()
        .outer_iter()
        .map(|r| r.to_vec())
        .collect()
}

fn bool_rows(a: &PyReadonlyArray2<'_, bool>) -> Vec<Vec<bool>> {
    a.as_array().outer_iter().map(|r| r.to_vec()).collect()
}

fn matrix(a: &PyReadonlyArray2<'_, f64>) -> nalgebra::DMatrix<f64> {
    let v = a.as_array();
    nalgebra::DMatrix::from_fn(v.nrows(), v.ncols(), |i, j| v[(i, j)])
}

/// `n × m` nested rows as a 2-D numpy array.
pub(crate) fn array2<'py>(
    py: Python<'py>,
    rows: &[Vec<f64>],
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    PyArray2::from_vec2(py, rows).map_err(|e| error(py, "InternalError", e.to_string()))
}

/// The options of a call, its keyword arguments: fields of [`Options`] (`criterion`,
/// `samples`, …) and of [`PairInput`] other than the matrices (`blocks`, `coupling_tol`).
/// `None` means absent (the plan's default); a name neither type has is refused, as the
/// contract refuses an unknown field.
fn options(py: Python<'_>, kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<(Options, PairInput)> {
    if kwargs.is_none_or(|d| d.values().iter().all(|v| v.is_none())) {
        // Nothing given: every field absent, as an empty dict reads.
        return Ok((Options::default(), PairInput::default()));
    }
    let option_fields = field_names::<Options>().unwrap_or_default();
    let pair_fields = field_names::<PairInput>().unwrap_or_default();
    let given = PyDict::new(py);
    for (key, value) in kwargs.into_iter().flat_map(|d| d.iter()) {
        let name: String = key.extract()?;
        if value.is_none() {
            continue;
        }
        if !option_fields.contains(&name.as_str()) && !pair_fields.contains(&name.as_str()) {
            let known: Vec<&str> = option_fields.iter().chain(pair_fields).copied().collect();
            let message = format!(
                "unknown field `{name}`, expected one of {}",
                known.join(", ")
            );
            return Err(request_error(py, RequestError::invalid(&name, message)));
        }
        given.set_item(name, value)?;
    }
    // Each type takes its own fields and leaves the other's.
    let options: Options = contract_value(py, &given, None)?;
    let pair: PairInput = contract_value(py, &given, None)?;
    Ok((options, pair))
}

/// The rule named `method`: a name of the registry as it is, anything else as the contract reads
/// it (which names the field and the rules).
fn method_of(py: Python<'_>, method: &Bound<'_, PyString>) -> PyResult<Method> {
    match method
        .to_cow()
        .ok()
        .and_then(|name| Method::from_name(&name))
    {
        Some(m) => Ok(m),
        None => contract_value(py, method, Some("method")),
    }
}

/// One estimate of an N-way request: `(x or None, P)`.
type NumpyEstimate<'py> = (
    Option<PyReadonlyArray1<'py, f64>>,
    Bound<'py, PyArray2<f64>>,
);

/// The JSON contract as text: exactly `nmci fuse`.
#[pyfunction]
fn fuse_json(py: Python<'_>, request: String) -> PyResult<String> {
    detached(py, move || nmci::contract::fuse_json(&request))?.map_err(|e| request_error(py, e))
}

/// A request of the contract with its matrices as numpy arrays and its options as keyword
/// arguments ([`options`]; `criterion`, the option of every weighted rule, is a parameter, the
/// seventh, so a call that gives only it passes no keywords); the response as [`Fused`].
#[pyfunction]
#[pyo3(signature = (method, pa=None, pb=None, xa=None, xb=None, pab_unknown=None, criterion=None, estimates=None, patterns=None, **options))]
#[allow(clippy::too_many_arguments)]
fn fuse_arrays<'py>(
    py: Python<'py>,
    method: &Bound<'py, PyString>,
    pa: Option<Bound<'py, PyArray2<f64>>>,
    pb: Option<Bound<'py, PyArray2<f64>>>,
    xa: Option<Bound<'py, PyArray1<f64>>>,
    xb: Option<Bound<'py, PyArray1<f64>>>,
    pab_unknown: Option<PyReadonlyArray2<'py, bool>>,
    criterion: Option<&Bound<'py, PyAny>>,
    estimates: Option<Vec<NumpyEstimate<'py>>>,
    patterns: Option<Vec<(usize, usize, PyReadonlyArray2<'py, bool>)>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Fused> {
    let method = method_of(py, method)?;
    let (mut options, structure) = self::options(py, options)?;
    if let Some(criterion) = criterion.filter(|c| !c.is_none()) {
        options.criterion = Some(contract_value(py, criterion, Some("criterion"))?);
    }
    let pair = PairInput {
        pa: pa.as_ref().map(rows).unwrap_or_default(),
        pb: pb.as_ref().map(rows).unwrap_or_default(),
        xa: xa.map(|v| v.to_owned_array().to_vec()),
        xb: xb.map(|v| v.to_owned_array().to_vec()),
        pab_unknown: pab_unknown.as_ref().map(bool_rows),
        ..structure
    };
    let request = FuseRequest {
        pair,
        method,
        options,
        estimates: estimates.map(|list| {
            list.iter()
                .map(|(x, p)| NwayEstimate {
                    x: x.as_ref().map(|v| v.as_array().to_vec()),
                    p: rows(p),
                })
                .collect()
        }),
        patterns: patterns.map(|list| {
            list.iter()
                .map(|(i, j, m)| NwayPair {
                    i: *i,
                    j: *j,
                    pab_unknown: bool_rows(m),
                })
                .collect()
        }),
    };
    // The response goes into its `Arc` where it is made: a few hundred bytes not moved again.
    let response = detached(py, || nmci::contract::fuse(&request).map(Arc::new))?
        .map_err(|e| request_error(py, e))?;
    warn_structure(py, &response)?;
    Ok(Fused::new_from(py, response))
}

/// The response's structure note, if it has one (round-off absorbed, declared blocks, a weak
/// coupling kept), issued as a warning ([`warn`]).
fn warn_structure(py: Python<'_>, response: &FuseResponse) -> PyResult<()> {
    match response.structure.as_ref().and_then(|s| s.note.as_deref()) {
        Some(note) => warn(py, note),
        None => Ok(()),
    }
}

/// A stack's structure notes, if any, as one warning ([`warn`]): how many pairs have one, and
/// the first pair's.
fn warn_stack(py: Python<'_>, notes: &[Option<String>]) -> PyResult<()> {
    let mut given = (notes.iter().enumerate()).filter_map(|(i, n)| Some((i, n.as_deref()?)));
    let Some((first, note)) = given.next() else {
        return Ok(());
    };
    let count = 1 + given.count();
    let total = notes.len();
    warn(
        py,
        &format!("{count} of {total} pairs (the first, pair {first}): {note}"),
    )
}

/// `note` issued as `nmci.StructureWarning` at the user's line ([`user_stacklevel`]). An error
/// is what the warnings filter made of it.
fn warn(py: Python<'_>, note: &str) -> PyResult<()> {
    let category = py.import("nmci._errors")?.getattr("StructureWarning")?;
    let message = std::ffi::CString::new(note.replace('\0', " "))
        .map_err(|e| error(py, "InternalError", e.to_string()))?;
    PyErr::warn(py, &category, &message, user_stacklevel(py)?)
}

/// The `stacklevel` of the user's line for a warning issued here: the first frame, counting
/// from the Python caller of this extension (level 1), whose module is not the package (`nmci`
/// or `nmci.…`). A rule function may call `fuse_arrays` itself or through a helper, and the
/// Stone Soup plugin calls the rule functions: the warning points past all of them, as
/// Python 3.12's `skip_file_prefixes` would. Read only when a warning is issued.
fn user_stacklevel(py: Python<'_>) -> PyResult<i32> {
    let mut frame = py.import("sys")?.getattr("_getframe")?.call0()?;
    let mut level = 1;
    while !frame.is_none() {
        let module = frame.getattr("f_globals")?.get_item("__name__").ok();
        let name = module.as_ref().and_then(|m| m.extract::<String>().ok());
        if !name.is_some_and(|n| n == "nmci" || n.starts_with("nmci.")) {
            break;
        }
        frame = frame.getattr("f_back")?;
        level += 1;
    }
    Ok(level)
}

/// `k` pairs fused by one closed-form rule ([`nmci::contract::fuse_stack`]): `pa`, `pb`
/// `(k, n, n)`, `xa`, `xb` `(k, n)`, `pab_unknown` `(n, n)` or `(k, n, n)`; options as keyword
/// arguments, as [`fuse_arrays`] reads them.
#[pyfunction]
#[pyo3(signature = (method, pa, pb, xa=None, xb=None, pab_unknown=None, **options))]
#[allow(clippy::too_many_arguments)]
fn fuse_stack<'py>(
    py: Python<'py>,
    method: &Bound<'py, PyString>,
    pa: PyReadonlyArray3<'py, f64>,
    pb: PyReadonlyArray3<'py, f64>,
    xa: Option<PyReadonlyArray2<'py, f64>>,
    xb: Option<PyReadonlyArray2<'py, f64>>,
    pab_unknown: Option<Bound<'py, PyAny>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<FusedStack> {
    let method = method_of(py, method)?;
    let (options, structure) = self::options(py, options)?;
    let n = pa.shape()[1];
    if pa.shape()[2] != n {
        let message = format!(
            "`pa` must be a stack of square matrices (got shape {:?})",
            pa.shape()
        );
        return Err(request_error(py, RequestError::invalid("pa", message)));
    }
    let pattern: Option<Vec<bool>> = match &pab_unknown {
        None => None,
        Some(m) => {
            let m: numpy::PyReadonlyArrayDyn<'py, bool> = m.extract()?;
            Some(m.as_array().iter().copied().collect())
        }
    };
    // Contiguous copies (numpy's arrays may be strided); then the stack runs without the GIL.
    let (pa, pb) = (
        pa.as_array().iter().copied().collect::<Vec<_>>(),
        pb.as_array().iter().copied().collect::<Vec<_>>(),
    );
    let xa = xa.map(|v| v.as_array().iter().copied().collect::<Vec<_>>());
    let xb = xb.map(|v| v.as_array().iter().copied().collect::<Vec<_>>());
    let response = detached(py, || {
        stack(&StackRequest {
            method,
            options,
            n,
            pa: &pa,
            pb: &pb,
            xa: xa.as_deref(),
            xb: xb.as_deref(),
            pab_unknown: pattern.as_deref(),
            blocks: structure.blocks,
            coupling_tol: structure.coupling_tol,
        })
    })?
    .map_err(|e| request_error(py, e))?;
    warn_stack(py, &response.notes)?;
    FusedStack::new_from(py, method, response)
}

/// `k` fused estimates ([`fuse_stack`]): numpy arrays stacked along the first axis.
#[pyclass(module = "nmci._nmci", frozen, get_all)]
pub struct FusedStack {
    /// The rule.
    method: String,
    /// Fused estimates, `(k, n)`.
    x: Py<PyAny>,
    /// Bounds, `(k, n, n)`.
    #[pyo3(name = "P")]
    p: Py<PyAny>,
    /// `K_a`, `(k, n, n)`.
    #[pyo3(name = "Ka")]
    ka: Py<PyAny>,
    /// `K_b`, `(k, n, n)`.
    #[pyo3(name = "Kb")]
    kb: Py<PyAny>,
    /// `tr P` of each pair, `(k,)`.
    trace: Py<PyAny>,
    /// `det P` of each pair, `(k,)`.
    det: Py<PyAny>,
    /// The weight of each state, `(k, n)` (CI, ICI: one ω on every state; nmCI: the ω of the
    /// state's block); `None` for EI and naive fusion.
    omega: Py<PyAny>,
    /// nmCI: the blocks of each pair; `None` for the other rules.
    blocks: Py<PyAny>,
    /// Each pair's structure note, or `None`.
    structure_notes: Vec<Option<String>>,
}

impl FusedStack {
    fn new_from(
        py: Python<'_>,
        method: Method,
        r: nmci::contract::StackResponse,
    ) -> PyResult<Self> {
        let (k, n) = (r.count, r.n);
        let cube = |v: Vec<f64>| -> PyResult<Py<PyAny>> {
            Ok(PyArray1::from_vec(py, v)
                .reshape([k, n, n])?
                .into_any()
                .unbind())
        };
        let omega = match r.omega.is_empty() {
            true => py.None(),
            false => PyArray1::from_vec(py, r.omega)
                .reshape([k, n])?
                .into_any()
                .unbind(),
        };
        let blocks = match method {
            Method::Nmci => to_python(py, &r.blocks)?.unbind(),
            _ => py.None(),
        };
        Ok(Self {
            method: method.name().to_owned(),
            x: PyArray1::from_vec(py, r.x)
                .reshape([k, n])?
                .into_any()
                .unbind(),
            p: cube(r.p)?,
            ka: cube(r.ka)?,
            kb: cube(r.kb)?,
            trace: PyArray1::from_vec(py, r.trace).into_any().unbind(),
            det: PyArray1::from_vec(py, r.det).into_any().unbind(),
            omega,
            blocks,
            structure_notes: r.notes,
        })
    }
}

#[pymethods]
impl FusedStack {
    fn __len__(&self, py: Python<'_>) -> PyResult<usize> {
        self.trace.bind(py).len()
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        Ok(format!(
            "FusedStack(method={:?}, pairs={}, n={})",
            self.method,
            self.__len__(py)?,
            self.x.bind(py).getattr("shape")?.get_item(1)?
        ))
    }
}

/// A fused estimate: the contract's response (docs/contract.md), written by serde from the
/// Rust [`FuseResponse`], with numpy arrays for the estimate, the bound, the gains and the
/// weights.
///
/// Its attributes are the contract's fields ([`response_fields`]), `None` where the method
/// does not report one; `p`, `ka` and `kb` are named `P`, `Ka` and `Kb`. `r["field"]` reads
/// a field by its contract name.
///
/// The fields are converted to Python when first read: the arrays and numbers a filter reads
/// (`x`, `p`, `ka`, `kb`, `omega`, `trace`, `det`) one by one, the others all at once. A field
/// read twice is the same object.
#[pyclass(module = "nmci._nmci", frozen)]
pub struct Fused {
    /// The fields converted so far (all of them once `rest` is `None`), in the order of the
    /// complete response.
    fields: Py<PyDict>,
    /// The response, until every field is converted ([`Fused::complete`]). The lock is held
    /// only to read or take it, never while Python runs (a conversion may run Python code).
    rest: Mutex<Option<Arc<FuseResponse>>>,
}

/// The attributes named as in the paper rather than as in the contract.
const ALIASES: [(&str, &str); 3] = [("P", "p"), ("Ka", "ka"), ("Kb", "kb")];

/// Every field of `r` as Python values: serde writes the response, the bulk arrays go to numpy
/// from the typed response.
fn response_dict(py: Python<'_>, mut r: FuseResponse) -> PyResult<Bound<'_, PyDict>> {
    let x = std::mem::take(&mut r.x);
    let p = std::mem::take(&mut r.p);
    let gains = std::mem::replace(&mut r.gains, Gains::Nway(Vec::new()));
    let omega = r.omega();
    let weights = match &mut r.details {
        Details::Nway { weights, .. } => Some(std::mem::take(weights)),
        _ => None,
    };
    // Written by serde too (so the field keeps its place), then replaced by the array.
    let gain_certified_p = match &r.details {
        Details::Sdp(d) => d.gain_certified_p.clone(),
        Details::SdpCuts(d) => d.gain_certified_p.clone(),
        _ => None,
    };
    let fields = to_python(py, &r)?.cast_into::<PyDict>()?;
    fields.set_item("x", PyArray1::from_vec(py, x))?;
    fields.set_item("p", array2(py, &p)?)?;
    match gains {
        Gains::Pair { ka, kb } => {
            fields.del_item("gains").ok();
            fields.set_item("ka", array2(py, &ka)?)?;
            fields.set_item("kb", array2(py, &kb)?)?;
        }
        Gains::Nway(stack) => {
            let stack = PyArray3::from_vec3(py, &stack)
                .map_err(|e| error(py, "InternalError", e.to_string()))?;
            fields.set_item("gains", stack)?;
        }
    }
    if let Some(omega) = omega {
        fields.set_item("omega", PyArray1::from_vec(py, omega))?;
    }
    if let Some(weights) = weights {
        fields.set_item("weights", array2(py, &weights)?)?;
    }
    if let Some(p) = gain_certified_p {
        fields.set_item("gain_certified_p", array2(py, &p)?)?;
    }
    Ok(fields)
}

/// The field `name` of `r` as [`response_dict`] writes it, for the fields a filter reads; `None`
/// for the others (and for a field `r` does not carry).
fn bulk_field<'py>(
    py: Python<'py>,
    r: &FuseResponse,
    name: &str,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    Ok(match (name, &r.gains) {
        ("x", _) => Some(PyArray1::from_slice(py, &r.x).into_any()),
        ("p", _) => Some(array2(py, &r.p)?.into_any()),
        ("ka", Gains::Pair { ka, .. }) => Some(array2(py, ka)?.into_any()),
        ("kb", Gains::Pair { kb, .. }) => Some(array2(py, kb)?.into_any()),
        ("omega", _) => r
            .omega()
            .map(|omega| PyArray1::from_vec(py, omega).into_any()),
        ("trace", _) => Some(r.trace.into_pyobject(py)?.into_any()),
        ("det", _) => Some(r.det.into_pyobject(py)?.into_any()),
        _ => None,
    })
}

impl Fused {
    fn new_from(py: Python<'_>, r: Arc<FuseResponse>) -> Self {
        Self {
            fields: PyDict::new(py).unbind(),
            rest: Mutex::new(Some(r)),
        }
    }

    /// The response not yet converted, if any (a new reference to it).
    fn rest(&self) -> Option<Arc<FuseResponse>> {
        // A panic while the lock was held left the response as it was: still usable.
        self.rest.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// The field `name` (its contract name), converted if it was not yet; `None` when the
    /// response does not carry it.
    fn field<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Option<Bound<'py, PyAny>>> {
        let fields = self.fields.bind(py);
        if let Some(value) = fields.get_item(name)? {
            return Ok(Some(value));
        }
        let bulk = match self.rest() {
            None => return Ok(None),
            Some(r) => bulk_field(py, &r, name)?,
        };
        match bulk {
            Some(value) => {
                fields.set_item(name, &value)?;
                Ok(Some(value))
            }
            None => {
                self.complete(py)?;
                fields.get_item(name)
            }
        }
    }

    /// Every field converted, those read before kept as the objects they were.
    fn complete<'py>(&self, py: Python<'py>) -> PyResult<&Bound<'py, PyDict>> {
        let fields = self.fields.bind(py);
        let taken = self.rest.lock().unwrap_or_else(|e| e.into_inner()).take();
        let Some(r) = taken else {
            return Ok(fields);
        };
        let all = response_dict(py, Arc::unwrap_or_clone(r))?;
        for (key, value) in fields.iter() {
            all.set_item(key, value)?;
        }
        fields.clear();
        fields.update(all.as_mapping())?;
        Ok(fields)
    }
}

#[pymethods]
impl Fused {
    /// A response from its fields (what pickling stores).
    #[new]
    fn new(fields: Bound<'_, PyDict>) -> Self {
        Self {
            fields: fields.unbind(),
            rest: Mutex::new(None),
        }
    }

    fn __getnewargs__(&self, py: Python<'_>) -> PyResult<(Py<PyDict>,)> {
        Ok((self.complete(py)?.clone().unbind(),))
    }

    /// The contract's fields a response can carry ([`response_fields`]).
    #[classattr]
    #[pyo3(name = "FIELDS")]
    fn fields_list() -> Vec<&'static str> {
        response_fields().to_vec()
    }

    /// The attributes named as in the paper: `{"P": "p", "Ka": "ka", "Kb": "kb"}`.
    #[classattr]
    #[pyo3(name = "ALIASES")]
    fn aliases() -> std::collections::BTreeMap<&'static str, &'static str> {
        ALIASES.into_iter().collect()
    }

    fn __getattr__(&self, py: Python<'_>, name: &str) -> PyResult<Py<PyAny>> {
        let field = ALIASES
            .iter()
            .find(|(alias, _)| *alias == name)
            .map_or(name, |(_, field)| field);
        let renamed = ALIASES.iter().any(|(_, field)| *field == name);
        if renamed || !response_fields().contains(&field) {
            return Err(PyAttributeError::new_err(format!(
                "Fused has no attribute {name:?}"
            )));
        }
        Ok(match self.field(py, field)? {
            Some(value) => value.unbind(),
            None => py.None(),
        })
    }

    // The fields a filter reads, as getters: found on the type, not through `__getattr__`
    // (which Python calls only after a failed lookup).

    /// The fused estimate `x`.
    #[getter]
    fn x(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.__getattr__(py, "x")
    }

    /// The bound `P` (field `p`).
    #[getter(P)]
    #[allow(non_snake_case)]
    fn P(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.__getattr__(py, "P")
    }

    /// The gain `K_a` on `x_a` (field `ka`).
    #[getter(Ka)]
    #[allow(non_snake_case)]
    fn Ka(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.__getattr__(py, "Ka")
    }

    /// The gain `K_b` on `x_b` (field `kb`).
    #[getter(Kb)]
    #[allow(non_snake_case)]
    fn Kb(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.__getattr__(py, "Kb")
    }

    /// The weights `ω` (`None` for rules without).
    #[getter]
    fn omega(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.__getattr__(py, "omega")
    }

    /// `tr P`.
    #[getter]
    fn trace(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.__getattr__(py, "trace")
    }

    /// `det P`.
    #[getter]
    fn det(&self, py: Python<'_>) -> PyResult<Py<PyAny>> {
        self.__getattr__(py, "det")
    }

    fn __getitem__(&self, py: Python<'_>, key: &str) -> PyResult<Py<PyAny>> {
        match self.field(py, key)? {
            Some(value) => Ok(value.unbind()),
            None => Err(PyKeyError::new_err(key.to_owned())),
        }
    }

    fn __contains__(&self, py: Python<'_>, key: &str) -> PyResult<bool> {
        Ok(self.field(py, key)?.is_some())
    }

    /// The contract's fields present in this response.
    fn keys(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        Ok(self
            .complete(py)?
            .keys()
            .iter()
            .filter_map(|k| k.extract().ok())
            .collect())
    }

    /// The response with lists instead of arrays (the JSON `nmci fuse` prints).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for (key, value) in self.complete(py)?.iter() {
            let value = if value.hasattr("tolist")? {
                value.call_method0("tolist")?
            } else {
                value
            };
            out.set_item(key, value)?;
        }
        Ok(out)
    }

    /// How the blocks were found, when that is worth saying (near-zero couplings absorbed,
    /// declared blocks, a weak coupling keeping blocks merged): `structure["note"]`.
    #[getter]
    fn structure_note(&self, py: Python<'_>) -> PyResult<Option<String>> {
        if let Some(r) = self.rest() {
            return Ok(r.structure.as_ref().and_then(|s| s.note.clone()));
        }
        let Some(structure) = self.fields.bind(py).get_item("structure")? else {
            return Ok(None);
        };
        match structure.get_item("note") {
            Ok(note) => note.extract(),
            Err(_) => Ok(None),
        }
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let fields = self.complete(py)?;
        let mut shown = Vec::new();
        for key in [
            "method",
            "trace",
            "lower_bound",
            "upper_bound",
            "gap_closed",
        ] {
            if let Some(value) = fields.get_item(key)? {
                shown.push(format!("{key}={}", value.repr()?));
            }
        }
        Ok(format!("Fused({})", shown.join(", ")))
    }
}

/// `λ_max(P^{-1/2} E P^{-1/2})`.
#[pyfunction]
#[allow(non_snake_case)]
fn conservativeness_index(
    py: Python<'_>,
    P: PyReadonlyArray2<'_, f64>,
    E: PyReadonlyArray2<'_, f64>,
) -> PyResult<f64> {
    // P a covariance; E of its size, finite and symmetric (checked by the Rust API).
    let (P, E) = (matrix(&P), matrix(&E));
    detached(py, move || nmci::check::conservativeness_index(&P, &E))?
        .map_err(|e| error_at(py, "InputError", e.to_string(), e.request_field()))
}

/// Admissible cross-covariances `P_ab'` (a `count × n × n` array) and the trials used; the
/// sampler's options (`seed`, `sampler`, `max_trials`) as keyword arguments, read as a
/// request's.
#[pyfunction]
#[pyo3(signature = (pa, pb, pab_unknown, count, **options))]
fn sample_cross_covariances<'py>(
    py: Python<'py>,
    pa: Bound<'py, PyArray2<f64>>,
    pb: Bound<'py, PyArray2<f64>>,
    pab_unknown: Option<PyReadonlyArray2<'py, bool>>,
    count: &Bound<'py, PyAny>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<(Bound<'py, PyArray3<f64>>, u64)> {
    let count: usize = contract_value(py, count, Some("count"))?;
    let (options, _) = self::options(py, options)?;
    // The request's problem builder and plan: the same checks, defaults and messages as `fuse`.
    let pair = PairInput {
        pab_unknown: pab_unknown.as_ref().map(bool_rows),
        ..PairInput::new(rows(&pa), rows(&pb))
    };
    let problem = pair
        .problem()
        .map_err(|e| request_error(py, RequestError::Input(e)))?;
    let sdp = options.plan().map_err(|e| request_error(py, e))?.sdp;
    let (seed, settings) = (sdp.seed, sdp.sampler);
    let samples = detached(py, move || {
        nmci::sample::sample_cross_covariances(&problem, count, seed, settings)
    })?
    .map_err(|e| request_error(py, RequestError::Sample(e)))?;
    let n = pa.shape()[0];
    let flat: Vec<f64> = samples
        .cross
        .iter()
        .flat_map(|m| m.transpose().iter().copied().collect::<Vec<_>>())
        .collect();
    let array = PyArray1::from_vec(py, flat).reshape([samples.cross.len(), n, n])?;
    Ok((array, samples.trials))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fuse_json, m)?)?;
    m.add_function(wrap_pyfunction!(fuse_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(conservativeness_index, m)?)?;
    m.add_function(wrap_pyfunction!(sample_cross_covariances, m)?)?;
    m.add_function(wrap_pyfunction!(fuse_stack, m)?)?;
    m.add_class::<Fused>()?;
    m.add_class::<FusedStack>()?;
    Ok(())
}
