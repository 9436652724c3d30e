//! The wasm-bindgen bindings: a thin layer over [`crate::contract::fuse`], [`crate::explore::explore`], the
//! fig. 2 study ([`crate::fig2::fig2_run`]) and the tracking study ([`crate::sim::LiveStudy`]). No logic lives here.
//!
//! The npm package's API is `fuse`, `rules`, `contract_fields`, `explore`, `prove` and
//! `version`, typed in `npm/index.d.ts`. The page's own exports (its panic hook, the study's
//! and fig. 2's workers, the chart drawing) and the test hook are `skip_typescript`: they are
//! in the module for the page, not declared for users.

use serde::de::DeserializeOwned;
use serde::Serialize;
use wasm_bindgen::prelude::*;

use crate::api::FuseRequest;
use crate::error::RequestError;
use crate::explore::ExploreRequest;
use crate::fig2::{Fig2Config, Fig2Record};
use crate::sim::{CoinTail, LiveCoin, LiveCoinPart, LiveRules, LiveStudy, StudyConfig, TraceTail};

#[cfg(feature = "charts")]
mod canvas;

/// A request object, parsed exactly as the CLI parses JSON: through a `serde_json::Value`,
/// because serde-wasm-bindgen alone skips unknown fields instead of rejecting them.
fn parse<T: DeserializeOwned>(request: JsValue) -> Result<T, RequestError> {
    serde_json::from_value(value_of(request)?).map_err(|e| RequestError::Malformed(e.to_string()))
}

/// A JS object as a `serde_json::Value` (a NaN becomes `null`, as in `JSON.stringify`).
fn value_of(request: JsValue) -> Result<serde_json::Value, RequestError> {
    serde_wasm_bindgen::from_value(request).map_err(|e| RequestError::Malformed(e.to_string()))
}

/// An object this module gave out (a chart, fig. 2's rows), read back as it is: NaN stays NaN
/// (the JSON route of [`parse`] has no NaN).
fn parse_own<T: DeserializeOwned>(value: JsValue) -> Result<T, JsError> {
    serde_wasm_bindgen::from_value(value).map_err(|e| JsError::new(&e.to_string()))
}

/// A request's error as a thrown JS `Error` whose `field` names the request field at fault
/// ([`RequestError::field`]; absent when no single field is).
fn thrown(error: RequestError) -> JsValue {
    let object = js_sys::Error::new(&error.to_string());
    if let Some(field) = error.field() {
        // Setting a property on a fresh Error object cannot fail.
        let _ = js_sys::Reflect::set(&object, &"field".into(), &field.into());
    }
    object.into()
}

/// A response as a plain JS object (absent optional fields are left out, not `null`).
fn to_js<T: Serialize>(value: &T) -> Result<JsValue, JsError> {
    // Maps as plain objects: a struct with a flattened part (the explorer's `Gap`) is written
    // through serde's map interface, and the page reads it as an object.
    let serializer = serde_wasm_bindgen::Serializer::new()
        .serialize_missing_as_null(false)
        .serialize_maps_as_objects(true);
    Ok(value.serialize(&serializer)?)
}

/// Runs a fusion request (the same object as `nmci fuse` reads) and returns the response
/// object; throws an `Error` carrying the message of any invalid input and, in `field`, the
/// request field at fault.
/// An array of requests gives the array of their responses ([`crate::contract::fuse_list`]);
/// the first that fails throws, naming its index.
#[wasm_bindgen]
pub fn fuse(request: JsValue) -> Result<JsValue, JsValue> {
    // Named errors (a NaN's path, an unknown method, not an object): `api::json`.
    let value = value_of(request).map_err(thrown)?;
    if let serde_json::Value::Array(values) = value {
        let requests = crate::api::requests_from(values).map_err(thrown)?;
        let responses = crate::api::fuse_list(&requests).map_err(thrown)?;
        return Ok(to_js(&responses)?);
    }
    let request: FuseRequest = crate::api::json::from_value(value, "a request").map_err(thrown)?;
    let response = crate::api::fuse(&request).map_err(thrown)?;
    Ok(to_js(&response)?)
}

/// Installs the page's panic hook (each worker calls it once after `init`). wasm32 aborts on a
/// panic: the call ends in a `WebAssembly.RuntimeError` ("unreachable") and the instance must
/// not be used again. The hook runs first and stores the panic's message on the global object
/// as `nmciPanic`, so the worker can report what happened before the page replaces it
/// (`www/crash.js`).
#[wasm_bindgen(skip_typescript)]
pub fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        // Setting a property on the global object cannot fail.
        let _ = js_sys::Reflect::set(
            &js_sys::global(),
            &"nmciPanic".into(),
            &info.to_string().into(),
        );
    }));
}

/// Test-only: panics with `message`. The end-to-end test calls it through the explorer's
/// worker to check that a panic is reported and the worker replaced; the page never does.
/// Left out of the package's TypeScript declarations (a test hook, not an API).
#[wasm_bindgen(skip_typescript)]
pub fn panic_for_test(message: &str) {
    panic!("{message}");
}

/// The contract's field names, `{ request, response }` ([`crate::contract::request_fields`],
/// [`crate::contract::response_fields`]): what the npm package's TypeScript types declare.
#[wasm_bindgen]
pub fn contract_fields() -> Result<JsValue, JsError> {
    #[derive(Serialize)]
    struct Fields {
        request: Vec<String>,
        response: &'static [&'static str],
    }
    to_js(&Fields {
        request: crate::api::request_fields(),
        response: crate::api::response_fields(),
    })
}

/// Every fusion rule ([`crate::rules::RULES`]): name, label, legend, guarantee, colour, criteria,
/// options, whether it fuses N estimates and whether the explorer computes it.
#[wasm_bindgen]
pub fn rules() -> Result<JsValue, JsError> {
    to_js(&crate::rules::RULES)
}

/// The tracking study's estimators in report order ([`crate::sim::estimators`]): name, label,
/// colour and whether the charts draw it.
#[wasm_bindgen(skip_typescript)]
pub fn study_estimators() -> Result<JsValue, JsError> {
    to_js(&crate::sim::estimators().collect::<Vec<_>>())
}

thread_local! {
    /// The certified blocks [`explore`] keeps between calls.
    static EXPLORE_MEMO: std::cell::RefCell<crate::certify::CertificateMemo> = Default::default();
}

/// Analyses one explorer state (see [`crate::explore::ExploreRequest`]): CI, nmCI, the sampled-SDP
/// bound, the gap, the region of possible true fused covariances and each rule's worst
/// conservativeness margin. The region crosses as a `Float64Array` in `region`
/// (`region_count` row-major `n × n` matrices).
/// Throws as [`fuse`] does.
/// The certified rule's blocks are memoized per module instance (one per worker,
/// [`crate::explore::explore_with_memo`]): the same numbers, an edit in one block solves that block.
#[wasm_bindgen]
pub fn explore(request: JsValue) -> Result<JsValue, JsValue> {
    let request: ExploreRequest = parse(request).map_err(thrown)?;
    let analysis = EXPLORE_MEMO
        .with(|memo| crate::explore::explore_with_memo(&request, &mut memo.borrow_mut()))
        .map_err(thrown)?;
    let object = to_js(&analysis)?;
    let region = js_sys::Float64Array::from(analysis.region.as_slice());
    js_sys::Reflect::set(&object, &"region".into(), &region)
        .map_err(|_| JsError::new("cannot attach the region to the result"))?;
    Ok(object)
}

/// The explorer's second stage on one state ([`crate::explore::prove`]): the cutting-plane SDP's
/// proven bracket (`null` when the loop has none). The page sends it the request of
/// [`explore`], with a `time_limit`. Throws as [`fuse`] does.
#[wasm_bindgen]
pub fn prove(request: JsValue) -> Result<JsValue, JsValue> {
    let request: ExploreRequest = parse(request).map_err(thrown)?;
    let proof = crate::explore::prove(&request).map_err(thrown)?;
    Ok(to_js(&proof)?)
}

/// The tracking study advanced a few steps at a time (for a Web Worker with live plots).
#[wasm_bindgen(skip_typescript)]
pub struct Study {
    inner: LiveStudy,
}

#[wasm_bindgen]
impl Study {
    /// A study from a configuration object with the keys of `configs/paper.toml` (every key
    /// optional; unknown keys are rejected); throws on an invalid configuration.
    #[wasm_bindgen(constructor)]
    pub fn new(config: JsValue) -> Result<Study, JsError> {
        let config: StudyConfig = parse(config)?;
        Ok(Study {
            inner: LiveStudy::new(config)?,
        })
    }

    /// As the constructor, running the rules of `WORKER_RULES[0]` only
    /// ([`crate::sim::LiveStudy::with_second_worker`]): those of `WORKER_RULES[1]` come from a
    /// [`StudyRules`] in a second worker, through [`Study::absorb`].
    pub fn with_second_worker(config: JsValue) -> Result<Study, JsError> {
        let config: StudyConfig = parse(config)?;
        Ok(Study {
            inner: LiveStudy::with_second_worker(config)?,
        })
    }

    /// Takes a tail of the second worker's steps ([`StudyRules::tail`], as it gave it); throws
    /// when it does not continue where the previous one ended or passes this worker's steps.
    pub fn absorb(&mut self, tail: JsValue) -> Result<(), JsError> {
        let tail: TraceTail = parse_own(tail)?;
        Ok(self.inner.absorb(tail)?)
    }

    /// Whether it waits for the second worker's steps up to where its own runs are (then
    /// `advance` does nothing).
    pub fn waiting(&self) -> bool {
        self.inner.waiting()
    }

    /// Advances by up to `steps` time steps (of every run together, then of the exact COIN);
    /// returns whether the study is finished.
    pub fn advance(&mut self, steps: usize) -> Result<bool, JsError> {
        Ok(self.inner.advance(steps)?)
    }

    /// The charts so far, `{nees, rmse, omega, coin}` ([`crate::study::study_charts`]; `coin` only
    /// with COIN), for [`draw_chart`].
    pub fn charts(&self) -> Result<JsValue, JsError> {
        let object = js_sys::Object::new();
        for (name, chart) in self.inner.charts() {
            js_sys::Reflect::set(&object, &name.into(), &to_js(&chart)?)
                .map_err(|_| JsError::new("cannot attach a chart"))?;
        }
        Ok(object.into())
    }

    /// The current snapshot ([`crate::sim::StudyView`]); the series cross as `Float64Array`s
    /// `nees`, `rmse`, `two_sigma` (`5 × series_len`), `omega` (`(2 + blocks) × series_len`)
    /// and `coin` (`5 × coin_len`).
    pub fn view(&self) -> Result<JsValue, JsError> {
        let view = self.inner.view();
        let object = to_js(&view)?;
        for (name, values) in [
            ("nees", &view.nees),
            ("rmse", &view.rmse),
            ("two_sigma", &view.two_sigma),
            ("omega", &view.omega),
            ("coin", &view.coin),
        ] {
            let array = js_sys::Float64Array::from(values.as_slice());
            js_sys::Reflect::set(&object, &name.into(), &array)
                .map_err(|_| JsError::new("cannot attach a series to the view"))?;
        }
        Ok(object)
    }
}

/// The runs of a study for the rules of `WORKER_RULES[1]`, advanced a few steps at a time:
/// what the page runs in a second Web Worker beside the [`Study`] that runs the other rules
/// ([`crate::sim::LiveRules`]).
#[wasm_bindgen(skip_typescript)]
pub struct StudyRules {
    inner: LiveRules,
}

#[wasm_bindgen]
impl StudyRules {
    /// From a study configuration object (the keys of `configs/paper.toml`; `coin` is not
    /// consulted); throws on an invalid configuration.
    #[wasm_bindgen(constructor)]
    pub fn new(config: JsValue) -> Result<StudyRules, JsError> {
        let config: StudyConfig = parse(config)?;
        Ok(StudyRules {
            inner: LiveRules::new(config)?,
        })
    }

    /// Advances every run by up to `steps` time steps; returns whether they are done.
    pub fn advance(&mut self, steps: usize) -> Result<bool, JsError> {
        Ok(self.inner.advance(steps)?)
    }

    /// The steps since the previous tail ([`crate::sim::TraceTail`]), for [`Study::absorb`].
    pub fn tail(&mut self) -> Result<JsValue, JsError> {
        to_js(&self.inner.tail())
    }
}

/// The exact COIN of a study on its own, advanced a few estimator-steps at a time: what the
/// page runs in a second Web Worker beside the runs ([`crate::sim::LiveCoin`]).
#[wasm_bindgen(skip_typescript)]
pub struct StudyCoin {
    inner: LiveCoin,
}

#[wasm_bindgen]
impl StudyCoin {
    /// From a study configuration object (the keys of `configs/paper.toml`; `coin` is not
    /// consulted); throws on an invalid configuration.
    #[wasm_bindgen(constructor)]
    pub fn new(config: JsValue) -> Result<StudyCoin, JsError> {
        let config: StudyConfig = parse(config)?;
        Ok(StudyCoin {
            inner: LiveCoin::new(config)?,
        })
    }

    /// As the constructor, propagating the estimators of `COIN_WORKER_ESTIMATORS[0]` only
    /// ([`crate::sim::LiveCoin::with_second_worker`]): those of `COIN_WORKER_ESTIMATORS[1]`
    /// come from a [`StudyCoinPart`] in a second worker, through [`StudyCoin::absorb`].
    pub fn with_second_worker(config: JsValue) -> Result<StudyCoin, JsError> {
        let config: StudyConfig = parse(config)?;
        Ok(StudyCoin {
            inner: LiveCoin::with_second_worker(config)?,
        })
    }

    /// Takes a tail of the second worker's COIN steps ([`StudyCoinPart::tail`], as it gave
    /// it); throws when it does not continue where the previous one ended.
    pub fn absorb(&mut self, tail: JsValue) -> Result<(), JsError> {
        let tail: CoinTail = parse_own(tail)?;
        Ok(self.inner.absorb(tail)?)
    }

    /// Whether its own estimators are done and it waits for the second worker's steps (then
    /// `advance` does nothing).
    pub fn waiting(&self) -> bool {
        self.inner.waiting()
    }

    /// Advances by up to `units` estimator-steps; returns whether it is finished.
    pub fn advance(&mut self, units: usize) -> Result<bool, JsError> {
        Ok(self.inner.advance(units)?)
    }

    /// The current snapshot ([`crate::sim::CoinView`]); `coin` (`5 × coin_len`) crosses as a
    /// `Float64Array`.
    pub fn view(&self) -> Result<JsValue, JsError> {
        let view = self.inner.view();
        let object = to_js(&view)?;
        js_sys::Reflect::set(
            &object,
            &"coin".into(),
            &js_sys::Float64Array::from(view.coin.as_slice()),
        )
        .map_err(|_| JsError::new("cannot attach the series to the view"))?;
        Ok(object)
    }

    /// The COIN chart so far ([`crate::study::coin_chart`]), for [`draw_chart`].
    pub fn chart(&self) -> Result<JsValue, JsError> {
        to_js(&self.inner.chart())
    }
}

/// The exact COIN of the estimators of `COIN_WORKER_ESTIMATORS[1]`, advanced a few
/// estimator-steps at a time: what the page runs in a second COIN worker beside the
/// [`StudyCoin`] that propagates the others ([`crate::sim::LiveCoinPart`]).
#[wasm_bindgen(skip_typescript)]
pub struct StudyCoinPart {
    inner: LiveCoinPart,
}

#[wasm_bindgen]
impl StudyCoinPart {
    /// From a study configuration object (the keys of `configs/paper.toml`; `coin` is not
    /// consulted); throws on an invalid configuration.
    #[wasm_bindgen(constructor)]
    pub fn new(config: JsValue) -> Result<StudyCoinPart, JsError> {
        let config: StudyConfig = parse(config)?;
        Ok(StudyCoinPart {
            inner: LiveCoinPart::new(config)?,
        })
    }

    /// Advances by up to `units` estimator-steps; returns whether its estimators are done.
    pub fn advance(&mut self, units: usize) -> Result<bool, JsError> {
        Ok(self.inner.advance(units)?)
    }

    /// The steps since the previous tail ([`crate::sim::CoinTail`]), for [`StudyCoin::absorb`].
    pub fn tail(&mut self) -> Result<JsValue, JsError> {
        to_js(&self.inner.tail())
    }
}

/// The network of a study configuration (the keys of `configs/paper.toml`, every key
/// optional), drawn: `{svg, text_mismatch}`, `text_mismatch` `undefined` when the network
/// fits the paper's text ([`crate::sim::check_text`]) and otherwise why not. Throws on an
/// invalid configuration.
#[wasm_bindgen(skip_typescript)]
pub fn study_network(config: JsValue) -> Result<JsValue, JsError> {
    #[derive(Serialize)]
    struct Network {
        svg: String,
        text_mismatch: Option<String>,
    }
    let config: StudyConfig = parse(config)?;
    config.validate()?;
    to_js(&Network {
        svg: crate::sim::network_svg(&config.scenario, config.agent, config.watched),
        text_mismatch: crate::sim::check_text(&config.scenario)
            .err()
            .map(|e| e.to_string()),
    })
}

/// The named networks, as links between groups (1-based pairs, beside the rings): `paper`,
/// the default (the best fit of `nmci sweep`), and `figure`, the bridges read from the
/// paper's figure ([`crate::sim::FIGURE_BRIDGES`]).
#[wasm_bindgen(skip_typescript)]
pub fn study_networks() -> Result<JsValue, JsError> {
    #[derive(Serialize)]
    struct Networks {
        paper: Vec<(usize, usize)>,
        figure: Vec<(usize, usize)>,
    }
    to_js(&Networks {
        paper: StudyConfig::default().scenario.bridges,
        figure: crate::sim::FIGURE_BRIDGES.to_vec(),
    })
}

/// Run `run` of the paper's fig. 2 study ([`crate::fig2::fig2_run`]): `config` has the keys of
/// [`crate::fig2::Fig2Config`] (`runs`, `sizes`, `seed`); returns one record per sample-set size.
#[wasm_bindgen(skip_typescript)]
pub fn fig2_run(config: JsValue, run: usize) -> Result<JsValue, JsError> {
    let config: Fig2Config = parse(config)?;
    to_js(&crate::fig2::fig2_run(&config, run)?)
}

/// The rows of `fig2.csv` ([`crate::fig2::fig2_summary`]) from the records of the runs done so far.
#[wasm_bindgen(skip_typescript)]
pub fn fig2_summary(config: JsValue, runs: JsValue) -> Result<JsValue, JsError> {
    let config: Fig2Config = parse(config)?;
    let runs: Vec<Vec<Fig2Record>> = parse(runs)?;
    to_js(&crate::fig2::fig2_summary(&config, &runs))
}

/// Draws a chart ([`crate::chart::Chart`], as `Study.charts()` and [`fig2_charts`] give it) onto
/// `canvas`, `width` × `height` CSS pixels, with the code that writes the CLI's SVG files
/// ([`crate::chart::draw`]); returns the number of points drawn per line. Throws when the
/// object is not a chart or the canvas cannot be drawn on. Feature `charts` (the page's build).
#[cfg(feature = "charts")]
#[wasm_bindgen(skip_typescript)]
pub fn draw_chart(
    canvas: web_sys::HtmlCanvasElement,
    chart: JsValue,
    width: u32,
    height: u32,
) -> Result<Vec<u32>, JsError> {
    use plotters::prelude::IntoDrawingArea;
    // Below this the axes' label areas no longer fit.
    const MIN: (u32, u32) = (200, 120);
    if width < MIN.0 || height < MIN.1 || width > 8192 || height > 8192 {
        return Err(JsError::new(&format!(
            "a chart needs {}…8192 × {}…8192 CSS pixels (got {width} × {height})",
            MIN.0, MIN.1
        )));
    }
    let chart: crate::chart::Chart = parse_own(chart)?;
    let backend = canvas::CanvasBackend::new(&canvas, width, height)
        .map_err(|e| JsError::new(&e.to_string()))?;
    let area = backend.into_drawing_area();
    crate::chart::draw(&chart, &area)
        .and_then(|()| area.present())
        .map_err(|e| JsError::new(&format!("cannot draw the chart: {e}")))?;
    Ok(chart.drawn_points().into_iter().map(|n| n as u32).collect())
}

/// A per-step series file of the study as `nmci track` writes it ([`crate::study::series_csv`]:
/// `nees.csv`, `rmse.csv`, `two_sigma.csv`, `coin.csv`) from a view's row-major series
/// (`series.len() / steps` estimators) and the time step.
#[wasm_bindgen(skip_typescript)]
pub fn study_series_csv(series: Vec<f64>, steps: usize, dt: f64) -> Result<String, JsError> {
    if steps == 0 || series.len() % steps != 0 {
        return Err(JsError::new(&format!(
            "{} values are not whole series of {steps} steps",
            series.len()
        )));
    }
    let rows: Vec<Vec<f64>> = series.chunks(steps).map(<[f64]>::to_vec).collect();
    Ok(crate::sim::series_csv(&rows, dt))
}

/// One of the study's charts (an object of `Study.charts()` or `StudyCoin`'s) as the SVG file
/// `nmci track` writes for it ([`crate::chart::charts_svg`] at [`crate::sim::STUDY_SVG_SIZE`]).
#[wasm_bindgen(skip_typescript)]
pub fn study_chart_svg(chart: JsValue) -> Result<String, JsError> {
    let chart: crate::chart::Chart = parse_own(chart)?;
    crate::chart::charts_svg(&[&chart], crate::sim::STUDY_SVG_SIZE)
        .map_err(|e| JsError::new(&format!("cannot draw the chart: {}", e.0)))
}

/// Fig. 2's files as `nmci fig2` writes them, from the rows of [`fig2_summary`] and the runs
/// they summarise: `fig2.csv` ([`crate::fig2::fig2_csv`]) or `fig2.svg` (its two charts at
/// [`crate::fig2::FIG2_SVG_SIZE`]).
#[wasm_bindgen(skip_typescript)]
pub fn fig2_file(name: &str, rows: JsValue, runs: usize) -> Result<String, JsError> {
    let rows: Vec<crate::fig2::Fig2Row> = parse_own(rows)?;
    match name {
        "fig2.csv" => Ok(crate::fig2::fig2_csv(&rows)),
        "fig2.svg" => {
            let [dev, eig] = crate::fig2::fig2_charts(&rows, runs);
            crate::chart::charts_svg(&[&dev, &eig], crate::fig2::FIG2_SVG_SIZE)
                .map_err(|e| JsError::new(&format!("cannot draw the charts: {}", e.0)))
        }
        other => Err(JsError::new(&format!(
            "fig. 2 writes fig2.csv and fig2.svg, not {other}"
        ))),
    }
}

/// Fig. 2's two charts ([`crate::fig2::fig2_charts`]) from the rows of [`fig2_summary`] and the
/// runs they summarise.
#[wasm_bindgen(skip_typescript)]
pub fn fig2_charts(rows: JsValue, runs: usize) -> Result<JsValue, JsError> {
    let rows: Vec<crate::fig2::Fig2Row> = parse_own(rows)?;
    to_js(&crate::fig2::fig2_charts(&rows, runs))
}

/// The crate version.
#[wasm_bindgen]
pub fn version() -> String {
    env!("CARGO_PKG_VERSION").into()
}
