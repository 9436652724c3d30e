//! `nmci._nmci`: the Python extension module, a thin layer over nmci's Rust API.
//!
//! The Python package `nmci` (python/nmci/__init__.py) wraps these functions in typed, documented
//! functions and classes. Here:
//! - arrays cross as numpy `float64` (and `bool` patterns) and go out as numpy arrays;
//! - requests go through the same [`nmci::contract::FuseRequest`] / [`nmci::contract::fuse`] contract as the CLI and
//!   the page (the array entry point fills the request's matrices from numpy instead of JSON),
//!   so every rule, default, check and error message is the Rust one;
//! - every solve, sample and study runs with the GIL released ([`Python::detach`]) and inside
//!   `catch_unwind`, so Python threads run in parallel and a Rust panic surfaces as
//!   `nmci.InternalError` instead of a crash;
//! - studies and fig. 2 run on a rayon pool built per call, never rayon's global pool, so they
//!   also run in processes forked from one that used nmci (Python's process pools on Linux);
//! - errors become the exceptions of `nmci._errors` (one class per Rust error concern).

use std::panic::{catch_unwind, AssertUnwindSafe};

use numpy::{PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use nmci::study::{MergeError, SimError, StudyConfig, StudyShard};
use nmci::{
    contract::{FuseRequest, FuseResponse, Gains},
    RequestError, SampleError, SolveError,
};

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

fn sim_error(py: Python<'_>, e: SimError) -> PyErr {
    let kind = match e {
        SimError::InvalidScenario(_) | SimError::InvalidConfig(_) | SimError::Workers(_) => {
            "StudyError"
        }
        SimError::Fusion(_) | SimError::Diverged(_) => "SimulationError",
    };
    error(py, kind, e.to_string())
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

fn rows(a: &PyReadonlyArray2<'_, f64>) -> Vec<Vec<f64>> {
    a.as_array().outer_iter().map(|r| r.to_vec()).collect()
}

fn bool_rows(a: &PyReadonlyArray2<'_, bool>) -> Vec<Vec<bool>> {
    a.as_array().outer_iter().map(|r| r.to_vec()).collect()
}

fn matrix(a: &PyReadonlyArray2<'_, f64>) -> nalgebra::DMatrix<f64> {
    let v = a.as_array();
    nalgebra::DMatrix::from_fn(v.nrows(), v.ncols(), |i, j| v[(i, j)])
}

/// A JSON value as a Python object (`null` → `None`, arrays → lists, objects → dicts).
fn to_python<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use pyo3::IntoPyObjectExt;
    Ok(match v {
        serde_json::Value::Null => py.None().into_bound(py),
        serde_json::Value::Bool(b) => b.into_bound_py_any(py)?,
        serde_json::Value::Number(n) => match (n.as_u64(), n.as_i64()) {
            (Some(u), _) => u.into_bound_py_any(py)?,
            (None, Some(i)) => i.into_bound_py_any(py)?,
            _ => n.as_f64().unwrap_or(f64::NAN).into_bound_py_any(py)?,
        },
        serde_json::Value::String(s) => s.into_bound_py_any(py)?,
        serde_json::Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(to_python(py, item)?)?;
            }
            list.into_any()
        }
        serde_json::Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, item) in map {
                dict.set_item(k, to_python(py, item)?)?;
            }
            dict.into_any()
        }
    })
}

/// `n × m` nested rows as a 2-D numpy array.
fn array2<'py>(py: Python<'py>, rows: &[Vec<f64>]) -> PyResult<Bound<'py, PyArray2<f64>>> {
    PyArray2::from_vec2(py, rows).map_err(|e| error(py, "InternalError", e.to_string()))
}

/// A response as a dict with the contract's keys: the estimate, bound and gains (`x`, `p`,
/// `ka`, `kb`, `gains`) go to numpy straight from the typed response, `omega` and `weights`
/// as numpy arrays from its JSON, the rest as in the JSON (the bulk arrays never become JSON
/// values).
fn response_dict<'py>(py: Python<'py>, mut r: FuseResponse) -> PyResult<Bound<'py, PyDict>> {
    let internal = |e: String| error(py, "InternalError", e);
    let x = std::mem::take(&mut r.x);
    let p = std::mem::take(&mut r.p);
    let gains = std::mem::replace(&mut r.gains, Gains::Nway(Vec::new()));
    let serde_json::Value::Object(mut map) =
        serde_json::to_value(&r).map_err(|e| internal(e.to_string()))?
    else {
        return Err(internal("a response serialises to an object".into()));
    };
    for key in ["x", "p", "ka", "kb", "gains"] {
        map.remove(key);
    }
    let floats = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .map(|a| a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect())
            .unwrap_or_default()
    };
    let mut arrays: Vec<(&str, Bound<'py, PyAny>)> = vec![
        ("x", PyArray1::from_vec(py, x).into_any()),
        ("p", array2(py, &p)?.into_any()),
    ];
    match gains {
        Gains::Pair { ka, kb } => {
            arrays.push(("ka", array2(py, &ka)?.into_any()));
            arrays.push(("kb", array2(py, &kb)?.into_any()));
        }
        Gains::Nway(stack) => {
            let gains = PyArray3::from_vec3(py, &stack).map_err(|e| internal(e.to_string()))?;
            arrays.push(("gains", gains.into_any()));
        }
    }
    if let Some(v) = map.remove("omega") {
        arrays.push(("omega", PyArray1::from_vec(py, floats(&v)).into_any()));
    }
    if let Some(v) = map.remove("weights") {
        let rows: Vec<Vec<f64>> = v
            .as_array()
            .map(|a| a.iter().map(floats).collect())
            .unwrap_or_default();
        arrays.push(("weights", array2(py, &rows)?.into_any()));
    }
    let dict = to_python(py, &serde_json::Value::Object(map))?.cast_into::<PyDict>()?;
    for (key, array) in arrays {
        dict.set_item(key, array)?;
    }
    Ok(dict)
}

/// One estimate of an N-way request: `(x or None, P)`.
type NumpyEstimate<'py> = (
    Option<PyReadonlyArray1<'py, f64>>,
    PyReadonlyArray2<'py, f64>,
);

/// The JSON contract as text: exactly `nmci fuse`.
#[pyfunction]
fn fuse_json(py: Python<'_>, request: String) -> PyResult<String> {
    detached(py, move || nmci::contract::fuse_json(&request))?.map_err(|e| request_error(py, e))
}

/// The key whose value holds byte column `column` (1-based) of `options`, a flat JSON object
/// written by the Python layer (`"key": value` pairs, no nesting).
fn option_at(options: &str, column: usize) -> Option<String> {
    let before = options.get(..column.checked_sub(1)?)?;
    let colon = before.rfind("\":")?;
    let open = before[..colon].rfind('"')?;
    Some(before[open + 1..colon].to_owned())
}

/// The JSON contract with the matrices given as numpy arrays: `options` is the rest of the
/// request as JSON text (method, criterion, samples, …).
#[pyfunction]
#[pyo3(signature = (options, pa=None, pb=None, xa=None, xb=None, pab_unknown=None, estimates=None, patterns=None))]
#[allow(clippy::too_many_arguments)]
fn fuse_arrays<'py>(
    py: Python<'py>,
    options: &str,
    pa: Option<PyReadonlyArray2<'py, f64>>,
    pb: Option<PyReadonlyArray2<'py, f64>>,
    xa: Option<PyReadonlyArray1<'py, f64>>,
    xb: Option<PyReadonlyArray1<'py, f64>>,
    pab_unknown: Option<PyReadonlyArray2<'py, bool>>,
    estimates: Option<Vec<NumpyEstimate<'py>>>,
    patterns: Option<Vec<(usize, usize, PyReadonlyArray2<'py, bool>)>>,
) -> PyResult<Bound<'py, PyDict>> {
    let mut request: FuseRequest = serde_json::from_str(options).map_err(|e| {
        let error = match option_at(options, e.column()) {
            // A value of the wrong type or range: named, since the text is not the user's.
            Some(field) if e.is_data() => {
                let message = e.to_string();
                let message = message.split(" at line ").next().unwrap_or(&message);
                RequestError::invalid(&field, format!("`{field}`: {message}"))
            }
            _ => RequestError::Malformed(e.to_string()),
        };
        request_error(py, error)
    })?;
    if let Some(pa) = &pa {
        request.pair.pa = rows(pa);
    }
    if let Some(pb) = &pb {
        request.pair.pb = rows(pb);
    }
    request.pair.xa = xa.map(|v| v.as_array().to_vec());
    request.pair.xb = xb.map(|v| v.as_array().to_vec());
    request.pair.pab_unknown = pab_unknown.as_ref().map(bool_rows);
    request.estimates = estimates.map(|list| {
        list.iter()
            .map(|(x, p)| nmci::contract::NwayEstimate {
                x: x.as_ref().map(|v| v.as_array().to_vec()),
                p: rows(p),
            })
            .collect()
    });
    request.patterns = patterns.map(|list| {
        list.iter()
            .map(|(i, j, m)| nmci::contract::NwayPair {
                i: *i,
                j: *j,
                pab_unknown: bool_rows(m),
            })
            .collect()
    });
    let response =
        detached(py, move || nmci::contract::fuse(&request))?.map_err(|e| request_error(py, e))?;
    response_dict(py, response)
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

/// Admissible cross-covariances `P_ab'` (a `count × n × n` array) and the trials used.
#[pyfunction]
#[pyo3(signature = (pa, pb, pab_unknown, count, seed, sampler, max_trials))]
#[allow(clippy::too_many_arguments)]
fn sample_cross_covariances<'py>(
    py: Python<'py>,
    pa: PyReadonlyArray2<'py, f64>,
    pb: PyReadonlyArray2<'py, f64>,
    pab_unknown: Option<PyReadonlyArray2<'py, bool>>,
    count: usize,
    seed: Option<u64>,
    sampler: Option<&str>,
    max_trials: Option<u64>,
) -> PyResult<(Bound<'py, PyArray3<f64>>, u64)> {
    let kind: Option<nmci::sample::SamplerKind> = sampler
        .map(|s| serde_json::from_value(serde_json::Value::from(s)))
        .transpose()
        .map_err(|e| {
            // serde's message lists the variants of `SamplerKind` itself.
            error(py, "RequestError", format!("invalid request: sampler: {e}"))
        })?;
    // The request's problem builder and options: the same checks, defaults and messages as
    // `fuse`.
    let pair = nmci::contract::PairInput {
        pab_unknown: pab_unknown.as_ref().map(bool_rows),
        ..nmci::contract::PairInput::new(rows(&pa), rows(&pb))
    };
    let problem = pair
        .problem()
        .map_err(|e| request_error(py, RequestError::Input(e)))?;
    let options = nmci::contract::Options {
        sampler: kind,
        seed,
        max_trials,
        ..Default::default()
    };
    let sdp = options.plan().map_err(|e| request_error(py, e))?.sdp;
    let (seed, settings) = (sdp.seed, sdp.sampler);
    let samples = detached(py, move || {
        nmci::sample::sample_cross_covariances(&problem, count, seed, settings)
    })?
    .map_err(|e| request_error(py, RequestError::Sample(e)))?;
    let stack: Vec<Vec<Vec<f64>>> = samples
        .cross
        .iter()
        .map(|m| m.row_iter().map(|r| r.iter().copied().collect()).collect())
        .collect();
    let n = pa.as_array().nrows();
    let array = if stack.is_empty() {
        PyArray3::zeros(py, [0, n, n], false)
    } else {
        PyArray3::from_vec3(py, &stack).map_err(|e| error(py, "InternalError", e.to_string()))?
    };
    Ok((array, samples.trials))
}

/// A study configuration (JSON text) from TOML text, defaults filled in.
#[pyfunction]
fn config_from_toml(py: Python<'_>, text: &str) -> PyResult<String> {
    let config = StudyConfig::from_toml(text).map_err(|e| sim_error(py, e))?;
    serde_json::to_string(&config).map_err(|e| error(py, "InternalError", e.to_string()))
}

/// The registry of rules ([`nmci::rules::RULES`]) as JSON text.
#[pyfunction]
fn rules_json() -> String {
    serde_json::to_string(&nmci::rules::RULES).expect("the registry serialises")
}

/// The JSON request field of an input named in an error (`P_a` → `pa`; [`nmci::request_field`]).
#[pyfunction]
fn request_field(name: &str) -> String {
    nmci::request_field(name)
}

/// The default study configuration as JSON text.
#[pyfunction]
fn default_config() -> String {
    serde_json::to_string(&StudyConfig::default()).expect("the default configuration serialises")
}

fn parse_config(py: Python<'_>, config: &str) -> PyResult<StudyConfig> {
    let config: StudyConfig = serde_json::from_str(config)
        .map_err(|e| sim_error(py, SimError::InvalidConfig(e.to_string())))?;
    config.validate().map_err(|e| sim_error(py, e))?;
    Ok(config)
}

/// A whole study: configuration, every run's trace and the summary.
#[pyclass(module = "nmci._nmci", frozen)]
struct Study {
    inner: nmci::study::Study,
}

#[pymethods]
impl Study {
    /// The configuration as JSON text.
    fn config_json(&self) -> String {
        serde_json::to_string(&self.inner.config).expect("a configuration serialises")
    }

    /// `summary.json` as JSON text.
    fn report_json(&self) -> String {
        serde_json::to_string(&self.inner.report()).expect("a report serialises")
    }

    /// The estimators' names in series order.
    fn estimators(&self) -> Vec<String> {
        self.inner
            .summary
            .estimators
            .iter()
            .map(|(name, _)| name.clone())
            .collect()
    }

    /// A per-estimator series (`nees`, `rmse`, `two_sigma`, `coin`, `omega_nmci`) as an
    /// `estimators × steps` (or `blocks × steps`) array.
    fn series2<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let s = &self.inner.summary;
        let rows = match name {
            "nees" => &s.nees_series,
            "rmse" => &s.rmse_series,
            "two_sigma" => &s.two_sigma_series,
            "coin" => &s.coin_series,
            "omega_nmci" => &s.omega_nmci_series,
            _ => return Err(error(py, "InternalError", format!("no series {name}"))),
        };
        if rows.is_empty() {
            return Ok(PyArray2::zeros(py, [0, self.inner.config.steps], false));
        }
        array2(py, rows)
    }

    /// A single series (`omega_ci`, `omega_ici`) per step.
    fn series1<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let s = &self.inner.summary;
        match name {
            "omega_ci" => Ok(PyArray1::from_slice(py, &s.omega_ci_series)),
            "omega_ici" => Ok(PyArray1::from_slice(py, &s.omega_ici_series)),
            _ => Err(error(py, "InternalError", format!("no series {name}"))),
        }
    }

    /// The 95 % bounds of the run-averaged NEES.
    fn nees_bounds(&self) -> (f64, f64) {
        self.inner.summary.nees_bounds
    }

    /// Writes what `nmci track` writes into `out`; returns the files.
    fn write(&self, py: Python<'_>, out: std::path::PathBuf) -> PyResult<Vec<String>> {
        let study = self.inner.clone();
        let files = detached(py, move || nmci::study::write_study(&study, &out))?
            .map_err(|e| error(py, "OutputError", e.to_string()))?;
        Ok(files.iter().map(|p| p.display().to_string()).collect())
    }
}

/// Runs `first_run..first_run + runs` of a study (see `nmci::study::merge_shards`).
#[pyclass(module = "nmci._nmci", frozen)]
struct Shard {
    inner: StudyShard,
}

#[pymethods]
impl Shard {
    /// A shard from its JSON text (what `to_json` and `nmci track --first-run` write).
    #[new]
    fn new(py: Python<'_>, text: &str) -> PyResult<Self> {
        let inner = serde_json::from_str(text)
            .map_err(|e| error(py, "MergeError", format!("not a study shard: {e}")))?;
        Ok(Self { inner })
    }

    /// The JSON text (the file `nmci track --first-run` writes).
    fn to_json(&self) -> String {
        serde_json::to_string(&self.inner).expect("a shard serialises")
    }

    /// Writes the JSON text to `path` (a file `nmci merge` reads).
    fn save(&self, py: Python<'_>, path: std::path::PathBuf) -> PyResult<()> {
        std::fs::write(&path, self.to_json()).map_err(|e| {
            error(
                py,
                "OutputError",
                format!("cannot write {}: {e}", path.display()),
            )
        })
    }

    /// Its file name, `shard-FIRST-END.json` (what `nmci track --first-run` writes).
    #[getter]
    fn file_name(&self) -> String {
        self.inner.file_name()
    }

    /// Index of the first run.
    #[getter]
    fn first_run(&self) -> usize {
        self.inner.first_run
    }

    /// Runs in the shard.
    #[getter]
    fn runs(&self) -> usize {
        self.inner.config.runs
    }

    /// Whether the shard carries the study's exact COIN (the shard holding run 0).
    #[getter]
    fn has_coin(&self) -> bool {
        self.inner.coin.is_some()
    }

    /// Pickling (process pools, Dask, Ray): rebuilt from the JSON text.
    fn __getnewargs__(&self) -> (String,) {
        (self.to_json(),)
    }
}

/// The shard files of a folder (`shard-*.json`), sorted by name.
#[pyfunction]
fn shard_files(py: Python<'_>, dir: std::path::PathBuf) -> PyResult<Vec<String>> {
    let files = nmci::study::shard_files(&dir).map_err(|e| {
        error(
            py,
            "MergeError",
            format!("cannot read {}: {e}", dir.display()),
        )
    })?;
    Ok(files.iter().map(|p| p.display().to_string()).collect())
}

/// Runs a whole study on every core.
#[pyfunction]
fn run_study(py: Python<'_>, config: &str) -> PyResult<Study> {
    let config = parse_config(py, config)?;
    let study = parallel(py, move || -> Result<_, SimError> {
        let model = nmci::study::Model::new(&config.scenario)?;
        nmci::study::study_parallel(&config, &model, || {})
    })?
    .map_err(|e| sim_error(py, e))?;
    Ok(Study { inner: study })
}

/// Runs a shard of a study on every core.
#[pyfunction]
fn run_shard(py: Python<'_>, config: &str, first_run: usize) -> PyResult<Shard> {
    let config = parse_config(py, config)?;
    let shard = parallel(py, move || -> Result<_, SimError> {
        let model = nmci::study::Model::new(&config.scenario)?;
        nmci::study::run_shard(&config, &model, first_run, || {})
    })?
    .map_err(|e| sim_error(py, e))?;
    Ok(Shard { inner: shard })
}

/// Merges shards into the one study.
#[pyfunction]
fn merge(py: Python<'_>, shards: Vec<PyRef<'_, Shard>>) -> PyResult<Study> {
    let shards: Vec<StudyShard> = shards.iter().map(|s| s.inner.clone()).collect();
    let study = detached(py, move || nmci::study::merge_shards(shards))?.map_err(|e| {
        let kind = match e {
            MergeError::Invalid(_) => "StudyError",
            _ => "MergeError",
        };
        error(py, kind, e.to_string())
    })?;
    Ok(Study { inner: study })
}

/// The rows of `fig2.csv` (one per sample-set size) and the number of runs behind them.
#[pyclass(module = "nmci._nmci", frozen)]
struct Fig2Rows {
    rows: Vec<nmci::fig2::Fig2Row>,
    runs: usize,
}

#[pymethods]
impl Fig2Rows {
    /// The rows as JSON text (a statistic over no finite value is `null`).
    fn json(&self) -> String {
        serde_json::to_string(&self.rows).expect("rows serialise")
    }

    /// Writes what `nmci fig2` writes (`fig2.csv`, `fig2.svg`) into `out`; returns the files.
    fn write(&self, py: Python<'_>, out: std::path::PathBuf) -> PyResult<Vec<String>> {
        let (rows, runs) = (self.rows.clone(), self.runs);
        let files = detached(py, move || nmci::fig2::write_fig2(&rows, runs, &out))?
            .map_err(|e| error(py, "OutputError", e.to_string()))?;
        Ok(files.iter().map(|p| p.display().to_string()).collect())
    }
}

/// The paper's fig. 2, runs in parallel.
#[pyfunction]
fn fig2(py: Python<'_>, runs: usize, sizes: Vec<usize>, seed: u64) -> PyResult<Fig2Rows> {
    use rayon::prelude::*;
    let config = nmci::fig2::Fig2Config { runs, sizes, seed };
    let rows = parallel(py, move || -> Result<_, RequestError> {
        config.validate()?;
        let records = (0..config.runs)
            .into_par_iter()
            .map(|r| nmci::fig2::fig2_run(&config, r))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(nmci::fig2::fig2_summary(&config, &records))
    })?
    .map_err(|e| request_error(py, e))?;
    Ok(Fig2Rows { rows, runs })
}

/// Panics inside a detached solve: the tests check it arrives as `nmci.InternalError`.
#[pyfunction]
fn _panic_for_test(py: Python<'_>) -> PyResult<()> {
    detached(py, || panic!("a panic raised on purpose by the tests"))
}

#[pymodule]
fn _nmci(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(fuse_json, m)?)?;
    m.add_function(wrap_pyfunction!(fuse_arrays, m)?)?;
    m.add_function(wrap_pyfunction!(conservativeness_index, m)?)?;
    m.add_function(wrap_pyfunction!(sample_cross_covariances, m)?)?;
    m.add_function(wrap_pyfunction!(config_from_toml, m)?)?;
    m.add_function(wrap_pyfunction!(default_config, m)?)?;
    m.add_function(wrap_pyfunction!(rules_json, m)?)?;
    m.add_function(wrap_pyfunction!(request_field, m)?)?;
    m.add_function(wrap_pyfunction!(run_study, m)?)?;
    m.add_function(wrap_pyfunction!(run_shard, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(shard_files, m)?)?;
    m.add_function(wrap_pyfunction!(fig2, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_test, m)?)?;
    m.add_class::<Study>()?;
    m.add_class::<Shard>()?;
    m.add_class::<Fig2Rows>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
