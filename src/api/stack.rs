//! Stacks: `k` two-estimate problems of one size, fused by one closed-form rule in one call —
//! what a multi-target tracker holds per frame, and what numpy users hold as `(k, n, n)` arrays.
//!
//! Each pair is the request [`super::fuse`] would get with that pair's matrices and the stack's
//! method and options, and its numbers are that request's, bit for bit (tested): the same
//! checks, the same structure handling (declared `blocks`, `coupling_tol`), the same rule, and
//! for a pair with a semi-definite covariance the same pseudo-inverse form
//! (`fusion::semidefinite`, [`super::semidefinite_pair`]) and note.
//! A stack takes the rules whose response is the estimate, its bound, the gains and the
//! weights — `ci`, `nmci`, `ici`, `ei`, `naive`; the SDPs and the certified rule report a
//! bracket or a certificate per pair and are called per pair.
//!
//! A stack that fails is [`RequestError::InStack`] of its first failing pair: its index and
//! its error, whose field is indexed by the pair (`pa[17]`).
//!
//! Natively, a stack of 64 pairs or more runs its pairs on rayon's thread pool when the pool
//! has more than one thread (`RAYON_NUM_THREADS` sets its size; one thread runs them in
//! order). Each pair is computed alone, by the same code, so the numbers do not depend on the
//! threads (tested); an error is still the first failing pair's, every pair having run.
//!
//! A list of whole requests, of any sizes and methods, is [`fuse_list`]: in JSON, an array of
//! requests (`nmci fuse`, the wasm `fuse`) gives the array of their responses.

use nalgebra::{DMatrix, DVector};

use crate::error::{InputError, RequestError};
use crate::fusion::rules::Method;
use crate::fusion::semidefinite::definiteness_refusal;
use crate::fusion::{Criterion, Fused, FusionProblem};
use crate::structure::{CrossPattern, StructureSettings};

use super::{
    check_blocks, fuse, semidefinite_pair, structured, ClosedForm, CovarianceSummary, Details,
    FuseRequest, FuseResponse, Options, PairInput, Structured,
};

/// `k` pairs of `n`-state estimates, row-major and contiguous: `pa`, `pb` hold `k · n · n`
/// numbers (pair `i`'s matrix at `i · n · n`), `xa`, `xb` `k · n`.
#[derive(Debug, Clone, PartialEq)]
pub struct StackRequest<'a> {
    /// The rule: `ci`, `nmci`, `ici`, `ei` or `naive`.
    pub method: Method,
    /// The options, as in a request (`criterion`; the others do not apply to these rules).
    pub options: Options,
    /// The states of each estimate.
    pub n: usize,
    /// `P_a` of every pair.
    pub pa: &'a [f64],
    /// `P_b` of every pair.
    pub pb: &'a [f64],
    /// `x_a` of every pair (default zeros).
    pub xa: Option<&'a [f64]>,
    /// `x_b` of every pair (default zeros).
    pub xb: Option<&'a [f64]>,
    /// The pattern of `P_ab`: `n · n` (every pair's) or `k · n · n` (one per pair); default
    /// all unknown.
    pub pab_unknown: Option<&'a [bool]>,
    /// A declared partition of the states, every pair's ([`PairInput::blocks`]).
    pub blocks: Option<Vec<Vec<usize>>>,
    /// The coupling tolerance, every pair's ([`PairInput::coupling_tol`]).
    pub coupling_tol: Option<f64>,
}

/// The fused stack, row-major and contiguous like the request: pair `i`'s `x` at `i · n`, its
/// `P`, `K_a`, `K_b` at `i · n · n`.
#[derive(Debug, Clone, PartialEq)]
pub struct StackResponse {
    /// Pairs.
    pub count: usize,
    /// States.
    pub n: usize,
    /// Fused estimates, `k · n`.
    pub x: Vec<f64>,
    /// Bounds, `k · n · n`.
    pub p: Vec<f64>,
    /// `K_a`, `k · n · n`.
    pub ka: Vec<f64>,
    /// `K_b`, `k · n · n`.
    pub kb: Vec<f64>,
    /// `tr P` of each pair.
    pub trace: Vec<f64>,
    /// `det P` of each pair.
    pub det: Vec<f64>,
    /// The weight of each state, `k · n`: CI's and ICI's one `ω` on every state, nmCI's `ω` of
    /// the state's block; empty for EI and naive fusion (no weight).
    pub omega: Vec<f64>,
    /// The blocks of each pair (nmCI; empty for the other rules).
    pub blocks: Vec<Vec<Vec<usize>>>,
    /// Each pair's structure note, when there is one ([`super::StructureDetails::note`]).
    pub notes: Vec<Option<String>>,
}

/// One pair's result: the fused estimate, the rule's details, the structure note.
type Pair = (Fused, Details, Option<String>);

/// From this many pairs on, a native stack runs its pairs on rayon's thread pool (when it has
/// more than one thread): a pair takes microseconds, a parallel split tens of them.
#[cfg(not(target_arch = "wasm32"))]
const PARALLEL_FROM: usize = 64;

impl StackResponse {
    /// A response with room for `count` pairs of `n` states.
    fn empty(count: usize, n: usize) -> Self {
        let nn = n * n;
        StackResponse {
            count,
            n,
            x: Vec::with_capacity(count * n),
            p: Vec::with_capacity(count * nn),
            ka: Vec::with_capacity(count * nn),
            kb: Vec::with_capacity(count * nn),
            trace: Vec::with_capacity(count),
            det: Vec::with_capacity(count),
            omega: Vec::new(),
            blocks: Vec::new(),
            notes: Vec::with_capacity(count),
        }
    }

    /// Appends one pair's result.
    fn push(&mut self, (fused, details, note): Pair) {
        let n = self.n;
        self.x.extend(fused.x.iter());
        // Row-major, as the request.
        for (to, m) in [
            (&mut self.p, &fused.P),
            (&mut self.ka, &fused.K_a),
            (&mut self.kb, &fused.K_b),
        ] {
            for r in 0..n {
                to.extend(m.row(r).iter());
            }
        }
        let (trace, det) = CovarianceSummary::trace_det(&fused.P);
        self.trace.push(trace);
        self.det.push(det);
        match details {
            Details::Omega(omega) => self.omega.extend(std::iter::repeat_n(omega, n)),
            Details::Blocks { omega, blocks } => {
                let mut per_state = vec![0.0; n];
                for (block, w) in blocks.iter().zip(&omega) {
                    block.iter().for_each(|&s| per_state[s] = *w);
                }
                self.omega.extend(per_state);
                self.blocks.push(blocks);
            }
            _ => {}
        }
        self.notes.push(note);
    }
}

/// Fuses every pair of `request` (see the module docs).
///
/// ```
/// use nmci::contract::{fuse_stack, Options, StackRequest};
/// // Two pairs of 2-state estimates, the paper's example and its mirror.
/// let pa = [3.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 4.0];
/// let pb = [1.0, 0.0, 0.0, 4.0, 3.0, 0.0, 0.0, 1.0];
/// let diagonal = [true, false, false, true];
/// let stack = fuse_stack(&StackRequest {
///     method: nmci::rules::Method::Nmci, options: Options::default(), n: 2,
///     pa: &pa, pb: &pb, xa: None, xb: None, pab_unknown: Some(&diagonal),
///     blocks: None, coupling_tol: None,
/// }).unwrap();
/// assert_eq!(stack.trace, [2.0, 2.0]);
/// assert_eq!(stack.omega, [0.0, 1.0, 1.0, 0.0]);
/// ```
pub fn fuse_stack(request: &StackRequest<'_>) -> Result<StackResponse, RequestError> {
    let rule = ClosedForm::of(request.method).ok_or_else(|| {
        RequestError::invalid(
            "method",
            format!(
                "a stack takes ci, nmci, ici, ei or naive; `{}` reports a bracket or a certificate per pair: fuse its pairs one by one",
                request.method.name()
            ),
        )
    })?;
    let (count, shared_pattern) = shape(request)?;
    let mut out = StackResponse::empty(count, request.n);
    if count == 0 {
        return Ok(out);
    }
    let stack = Stack::new(request, rule, shared_pattern)?;
    #[cfg(not(target_arch = "wasm32"))]
    if count >= PARALLEL_FROM && rayon::current_num_threads() > 1 {
        use rayon::prelude::*;
        let pairs: Vec<Result<Pair, RequestError>> =
            (0..count).into_par_iter().map(|i| stack.pair(i)).collect();
        for pair in pairs {
            out.push(pair?);
        }
        return Ok(out);
    }
    for i in 0..count {
        out.push(stack.pair(i)?);
    }
    Ok(out)
}

/// The stack's number of pairs, and whether one pattern stands for every pair's: every
/// field's length checked against `pa`'s.
fn shape(request: &StackRequest<'_>) -> Result<(usize, bool), RequestError> {
    let n = request.n;
    let nn = n * n;
    if n == 0 || request.pa.len() % nn != 0 {
        return Err(RequestError::invalid(
            "pa",
            format!(
                "`pa` holds {} numbers: not a stack of {n} × {n} matrices",
                request.pa.len()
            ),
        ));
    }
    let count = request.pa.len() / nn;
    let sized = |field: &str, len: Option<usize>, each: usize| match len {
        Some(len) if len != count * each => Err(RequestError::invalid(
            field,
            format!("`{field}` holds {len} numbers, expected {count} × {each} (the pairs of `pa`)"),
        )),
        _ => Ok(()),
    };
    sized("pb", Some(request.pb.len()), nn)?;
    sized("xa", request.xa.map(<[f64]>::len), n)?;
    sized("xb", request.xb.map(<[f64]>::len), n)?;
    let shared_pattern = match request.pab_unknown.map(<[bool]>::len) {
        None => true,
        Some(len) if len == nn => true,
        Some(len) if len == count * nn => false,
        Some(len) => {
            return Err(RequestError::invalid(
                "pab_unknown",
                format!("`pab_unknown` holds {len} entries, expected {nn} (every pair's) or {count} × {nn} (one per pair)"),
            ))
        }
    };
    Ok((count, shared_pattern))
}

/// An error of pair `index`, as the stack reports it.
fn in_stack(index: usize) -> impl Fn(RequestError) -> RequestError {
    move |e| RequestError::InStack {
        index,
        source: Box::new(e),
    }
}

/// What every pair of a stack shares: the request, its rule, criterion and structure
/// settings, and the pattern when one stands for all.
struct Stack<'r, 'a> {
    request: &'r StackRequest<'a>,
    rule: ClosedForm,
    criterion: Criterion,
    settings: StructureSettings,
    shared: Option<CrossPattern>,
}

impl<'r, 'a> Stack<'r, 'a> {
    /// The request's checks, which depend on the sizes and the options only: one pair's
    /// request stands for every pair's.
    fn new(
        request: &'r StackRequest<'a>,
        rule: ClosedForm,
        shared_pattern: bool,
    ) -> Result<Self, RequestError> {
        let (n, nn) = (request.n, request.n * request.n);
        let rows = |s: &[f64]| s.chunks(n).map(<[f64]>::to_vec).collect::<Vec<_>>();
        let first = FuseRequest {
            pair: PairInput {
                pa: rows(&request.pa[..nn]),
                pb: rows(&request.pb[..nn]),
                xa: request.xa.map(|v| v[..n].to_vec()),
                xb: request.xb.map(|v| v[..n].to_vec()),
                pab_unknown: request
                    .pab_unknown
                    .map(|m| m[..nn].chunks(n).map(<[bool]>::to_vec).collect()),
                blocks: request.blocks.clone(),
                coupling_tol: request.coupling_tol,
            },
            method: request.method,
            options: request.options.clone(),
            estimates: None,
            patterns: None,
        };
        let mut stack = Stack {
            request,
            rule,
            criterion: first.plan().map_err(in_stack(0))?.criterion,
            settings: first.pair.structure_settings(),
            shared: None,
        };
        if shared_pattern {
            stack.shared = Some(stack.own_pattern(0).map_err(|e| in_stack(0)(e.into()))?);
        }
        Ok(stack)
    }

    /// Pair `i`'s pattern as `PairInput::problem` builds it: the given one, else the declared
    /// blocks'.
    fn own_pattern(&self, i: usize) -> Result<CrossPattern, InputError> {
        let (n, nn) = (self.request.n, self.request.n * self.request.n);
        match (self.request.pab_unknown, &self.request.blocks) {
            (Some(m), _) => {
                // One pattern for every pair, or pair `i`'s (`shape`).
                let m = if m.len() == nn {
                    m
                } else {
                    &m[i * nn..(i + 1) * nn]
                };
                Ok(CrossPattern::from_fn(n, |r, c| m[r * n + c]))
            }
            (None, Some(blocks)) => CrossPattern::within_blocks(n, blocks),
            (None, None) => Ok(CrossPattern::fully_unknown(n)),
        }
    }

    fn pattern(&self, i: usize) -> Result<CrossPattern, RequestError> {
        match &self.shared {
            Some(p) => Ok(p.clone()),
            None => Ok(self.own_pattern(i)?),
        }
    }

    /// Pair `i`'s mean (zero when not given) and covariance.
    fn estimate(&self, v: Option<&[f64]>, p: &[f64], i: usize) -> (DVector<f64>, DMatrix<f64>) {
        let n = self.request.n;
        let x = match v {
            Some(v) => DVector::from_row_slice(&v[i * n..(i + 1) * n]),
            None => DVector::zeros(n),
        };
        (x, row_major(n, &p[i * n * n..(i + 1) * n * n]))
    }

    /// Pair `i` fused, exactly as its single request; its errors name it.
    fn pair(&self, i: usize) -> Result<Pair, RequestError> {
        self.fuse_pair(i).map_err(in_stack(i))
    }

    fn fuse_pair(&self, i: usize) -> Result<Pair, RequestError> {
        let request = self.request;
        let (xa, pa) = self.estimate(request.xa, request.pa, i);
        let (xb, pb) = self.estimate(request.xb, request.pb, i);
        let problem = match FusionProblem::new(xa, pa, xb, pb, self.pattern(i)?) {
            Ok(problem) => problem,
            // Semi-definite: the pseudo-inverse form, as the single request (its inputs read
            // again: only a refused pair pays for it).
            Err(e) if definiteness_refusal(&e) => {
                let (xa, pa) = self.estimate(request.xa, request.pa, i);
                let (xb, pb) = self.estimate(request.xb, request.pb, i);
                let p = semidefinite_pair(
                    request.method,
                    [&xa, &xb],
                    [&pa, &pb],
                    &self.pattern(i)?,
                    self.criterion,
                    e,
                )?;
                return Ok((p.fused, p.details, p.structure.note));
            }
            Err(e) => return Err(e.into()),
        };
        let Structured {
            problem, details, ..
        } = structured(problem, &self.settings, request.method)?;
        check_blocks(request.method, &problem)?;
        let (fused, rule_details) = self.rule.fuse(&problem, self.criterion)?;
        Ok((fused, rule_details, details.and_then(|s| s.note)))
    }
}

/// The `n × n` matrix whose rows are the consecutive `n`-number pieces of `s`.
fn row_major(n: usize, s: &[f64]) -> DMatrix<f64> {
    DMatrix::from_fn(n, n, |r, c| s[r * n + c])
}

/// Runs a list of requests, each exactly as [`fuse`] runs it alone; the responses in order. The
/// first request that fails stops the list with [`RequestError::InList`] (its index). The JSON
/// contract takes a list as an array of requests ([`super::fuse_json`], `nmci fuse`, the wasm
/// `fuse`).
///
/// ```
/// use nmci::contract::{fuse_list, FuseRequest};
/// use nmci::rules::Method;
/// let pair = || (vec![vec![3.0, 0.0], vec![0.0, 1.0]], vec![vec![1.0, 0.0], vec![0.0, 4.0]]);
/// let (pa, pb) = pair();
/// let ci = FuseRequest::new(Method::Ci, pa, pb);
/// let (pa, pb) = pair();
/// let mut nmci = FuseRequest::new(Method::Nmci, pa, pb);
/// nmci.pair.pab_unknown = Some(vec![vec![true, false], vec![false, true]]);
/// let both = fuse_list(&[ci, nmci]).unwrap();
/// assert!(both[0].trace > 3.0 && both[1].trace == 2.0);
/// ```
pub fn fuse_list(requests: &[FuseRequest]) -> Result<Vec<FuseResponse>, RequestError> {
    requests
        .iter()
        .enumerate()
        .map(|(index, request)| {
            fuse(request).map_err(|e| RequestError::InList {
                index,
                source: Box::new(e),
            })
        })
        .collect()
}

/// Requests read from JSON values, each as a request alone is; the first that is not a request
/// stops the list with [`RequestError::InList`] (its index).
pub(crate) fn requests_from(
    values: Vec<serde_json::Value>,
) -> Result<Vec<FuseRequest>, RequestError> {
    values
        .into_iter()
        .enumerate()
        .map(|(index, value)| {
            super::json::from_value(value, "a request").map_err(|e| RequestError::InList {
                index,
                source: Box::new(e),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request<'a>(method: Method, pa: &'a [f64], pb: &'a [f64]) -> StackRequest<'a> {
        StackRequest {
            method,
            options: Options::default(),
            n: 2,
            pa,
            pb,
            xa: None,
            xb: None,
            pab_unknown: None,
            blocks: None,
            coupling_tol: None,
        }
    }

    /// Every pair of a two-pair stack, for every stacked rule, is its single request bit for
    /// bit, its structure note included; the notes, per rule and pair.
    fn pairs_are_single_requests(pa: &[f64], pb: &[f64]) -> Vec<Vec<Option<String>>> {
        let rows = |s: &[f64]| s.chunks(2).map(<[f64]>::to_vec).collect::<Vec<_>>();
        let methods = [
            Method::Ci,
            Method::Nmci,
            Method::Ici,
            Method::Ei,
            Method::Naive,
        ];
        methods
            .into_iter()
            .map(|method| {
                let stack = fuse_stack(&request(method, pa, pb)).unwrap();
                for i in 0..2 {
                    let at = 4 * i..4 * i + 4;
                    let one = fuse(&FuseRequest::new(
                        method,
                        rows(&pa[at.clone()]),
                        rows(&pb[at.clone()]),
                    ))
                    .unwrap();
                    assert_eq!(&stack.p[at], one.p.concat().as_slice(), "{method:?}");
                    assert_eq!(stack.trace[i], one.trace);
                    let note = one.structure.as_ref().and_then(|s| s.note.clone());
                    assert_eq!(stack.notes[i], note, "{method:?}");
                }
                stack.notes
            })
            .collect()
    }

    #[test]
    fn a_pair_of_the_stack_is_the_single_request() {
        pairs_are_single_requests(
            &[3.0, 0.5, 0.5, 1.0, 2.0, -0.3, -0.3, 1.5],
            &[1.0, 0.2, 0.2, 4.0, 1.0, 0.0, 0.0, 1.0],
        );
    }

    /// A semi-definite pair takes the pseudo-inverse form, as its single request does (an
    /// `ici` stack's such pair fused by CI's, its note saying so).
    #[test]
    fn a_semidefinite_pair_is_the_single_request() {
        let notes = pairs_are_single_requests(
            &[3.0, 0.5, 0.5, 1.0, 1.0, 0.0, 0.0, 0.0],
            &[1.0, 0.2, 0.2, 4.0, 2.0, 0.0, 0.0, 3.0],
        );
        for pair in notes {
            assert!(pair[0].is_none());
            let note = pair[1].as_deref().unwrap();
            assert!(note.contains("pseudo-inverse form"), "{note}");
        }
    }

    #[test]
    fn a_failing_pair_is_named_with_its_field() {
        let pa = [3.0, 0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 1.0];
        let pb = [1.0, 0.0, 0.0, 4.0, 1.0, 0.0, 0.0, 1.0];
        let e = fuse_stack(&request(Method::Ci, &pa, &pb)).unwrap_err();
        assert!(matches!(e, RequestError::InStack { index: 1, .. }), "{e}");
        assert_eq!(e.field().as_deref(), Some("pa[1]"));
        assert!(e.to_string().starts_with("pair 1: P_a"), "{e}");
        let e = fuse_stack(&request(Method::Sdp, &pa, &pb)).unwrap_err();
        assert_eq!(e.field().as_deref(), Some("method"));
    }

    /// `k` pairs of random 3-state covariances, row-major ([`crate::linalg::test_spd`]).
    #[cfg(not(target_arch = "wasm32"))]
    fn random_stack(k: usize) -> (Vec<f64>, Vec<f64>) {
        let mut seed = 7;
        let mut stack = || -> Vec<f64> {
            (0..k)
                .flat_map(|_| {
                    crate::linalg::test_spd(3, &mut seed, 0.1)
                        .transpose()
                        .iter()
                        .copied()
                        .collect::<Vec<_>>()
                })
                .collect()
        };
        let pa = stack();
        (pa, stack())
    }

    #[cfg(not(target_arch = "wasm32"))]
    #[test]
    fn a_parallel_stack_is_the_one_thread_stack_and_names_the_first_failing_pair() {
        let k = 3 * PARALLEL_FROM;
        let (mut pa, pb) = random_stack(k);
        let on = |threads: usize, pa: &[f64], method: Method| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                fuse_stack(&StackRequest {
                    n: 3,
                    ..request(method, pa, &pb)
                })
            })
        };
        for method in [Method::Ci, Method::Nmci, Method::Ici] {
            let parallel = on(2, &pa, method).unwrap();
            assert_eq!(parallel, on(1, &pa, method).unwrap(), "{method:?}");
            // And pair by pair, the single request's numbers.
            let rows = |s: &[f64]| s.chunks(3).map(<[f64]>::to_vec).collect::<Vec<_>>();
            for i in [0, PARALLEL_FROM, k - 1] {
                let at = 9 * i..9 * i + 9;
                let one = fuse(&FuseRequest::new(
                    method,
                    rows(&pa[at.clone()]),
                    rows(&pb[at.clone()]),
                ))
                .unwrap();
                assert_eq!(
                    &parallel.p[at],
                    one.p.concat().as_slice(),
                    "{method:?} pair {i}"
                );
            }
        }
        // Two bad pairs: the error is the first's, whichever thread met it first.
        pa[9 * 150] = -1.0;
        pa[9 * 100] = -1.0;
        for threads in [1, 2] {
            let e = on(threads, &pa, Method::Ci).unwrap_err();
            assert!(matches!(e, RequestError::InStack { index: 100, .. }), "{e}");
        }
    }

    #[test]
    fn a_json_list_gives_the_list_of_responses_and_names_the_failing_request() {
        let one = r#"{"pa":[[3,0],[0,1]],"pb":[[1,0],[0,4]],"method":"ci"}"#;
        let single: serde_json::Value =
            serde_json::from_str(&crate::api::fuse_json(one).unwrap()).unwrap();
        let list: serde_json::Value =
            serde_json::from_str(&crate::api::fuse_json(&format!(" [{one}, {one}]")).unwrap())
                .unwrap();
        assert_eq!(list, serde_json::json!([single, single]));
        assert_eq!(crate::api::fuse_json("[]").unwrap().trim(), "[]");
        let bad = format!(r#"[{one}, {{"pa":[[-1]],"pb":[[1]],"method":"ci"}}]"#);
        let e = crate::api::fuse_json(&bad).unwrap_err();
        assert_eq!(e.field().as_deref(), Some("[1].pa"));
        assert!(e.to_string().starts_with("request 1: P_a"), "{e}");
        let unknown = format!(r#"[{{"pa":[[1]],"pb":[[1]],"method":"ci","colour":1}}, {one}]"#);
        let e = crate::api::fuse_json(&unknown).unwrap_err();
        assert_eq!(e.field().as_deref(), Some("[0].colour"));
    }
}
