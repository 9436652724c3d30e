//! The paper's studies: the tracking study ([`Study`], its shards [`Shard`] and their merge)
//! and fig. 2 ([`Fig2Rows`]). Configurations cross as dicts read by serde into
//! [`StudyConfig`]; reports go out as dicts written by serde.

use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;

use nmci::study::{MergeError, SimError, StudyConfig, StudyShard};
use nmci::RequestError;

use crate::fuse::array2;
use crate::{detached, error, parallel, request_error, to_python};

fn sim_error(py: Python<'_>, e: SimError) -> PyErr {
    let kind = match e {
        SimError::InvalidScenario(_) | SimError::InvalidConfig(_) | SimError::Workers(_) => {
            "StudyError"
        }
        SimError::Fusion(_) | SimError::Diverged(_) => "SimulationError",
    };
    error(py, kind, e.to_string())
}

/// A study configuration from a dict of its keys (missing keys take their defaults), checked.
fn config(py: Python<'_>, config: &Bound<'_, PyAny>) -> PyResult<StudyConfig> {
    let mut de = pythonize::Depythonizer::from_object(config);
    let config: StudyConfig = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let message = match e.path().to_string().as_str() {
            "." => e.into_inner().to_string(),
            path => format!("`{path}`: {}", e.into_inner()),
        };
        sim_error(py, SimError::InvalidConfig(message))
    })?;
    config.validate().map_err(|e| sim_error(py, e))?;
    Ok(config)
}

/// A study configuration (a dict) from TOML text, defaults filled in.
#[pyfunction]
fn config_from_toml<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    let config = StudyConfig::from_toml(text).map_err(|e| sim_error(py, e))?;
    to_python(py, &config)
}

/// The default study configuration (`configs/paper.toml`) as a dict.
#[pyfunction]
fn default_config(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_python(py, &StudyConfig::default())
}

/// A whole study: configuration, every run's trace and the summary.
#[pyclass(module = "nmci._nmci", frozen)]
struct Study {
    inner: nmci::study::Study,
}

#[pymethods]
impl Study {
    /// The configuration as a dict.
    fn config<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_python(py, &self.inner.config)
    }

    /// `summary.json` as a dict.
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_python(py, &self.inner.report())
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
fn run_study(py: Python<'_>, config: &Bound<'_, PyAny>) -> PyResult<Study> {
    let config = self::config(py, config)?;
    let study = parallel(py, move || -> Result<_, SimError> {
        let model = nmci::study::Model::new(&config.scenario)?;
        nmci::study::study_parallel(&config, &model, || {})
    })?
    .map_err(|e| sim_error(py, e))?;
    Ok(Study { inner: study })
}

/// Runs a shard of a study on every core.
#[pyfunction]
fn run_shard(py: Python<'_>, config: &Bound<'_, PyAny>, first_run: usize) -> PyResult<Shard> {
    let config = self::config(py, config)?;
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
    /// The rows as dicts (a statistic over no finite value is `None`).
    fn rows<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_python(py, &self.rows)
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

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(config_from_toml, m)?)?;
    m.add_function(wrap_pyfunction!(default_config, m)?)?;
    m.add_function(wrap_pyfunction!(run_study, m)?)?;
    m.add_function(wrap_pyfunction!(run_shard, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(shard_files, m)?)?;
    m.add_function(wrap_pyfunction!(fig2, m)?)?;
    m.add_class::<Study>()?;
    m.add_class::<Shard>()?;
    m.add_class::<Fig2Rows>()?;
    Ok(())
}
