//! A structure-aware generator of fusion requests for fuzzing the JSON contract (issue 17):
//! requests built from the contract's own fields, each field either well formed or broken in
//! one of the ways a caller can break it — wrong types, wrong and inconsistent sizes,
//! NaN / ±Infinity tokens, 1e308, subnormals, out-of-range numbers, missing and unknown
//! fields, truncated text, absurd and negative settings, N-way requests whose estimates and
//! patterns disagree. Well-formed matrices are small (at most 4 states) so that the requests
//! that do reach a solver finish quickly; absurd *sizes* are covered by the settings (samples,
//! trials, levels) and by the size limits' own tests.
//!
//! Deterministic: case `i` of a seed is the same text on every machine (the native fuzz and
//! the headless-Chromium share draw the same cases).
#![allow(dead_code)]

use nmci::rules::RULES;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Map, Value};

/// The seed of the stream both fuzz tests draw from (native `tests/native/fuzz.rs`, wasm
/// `tests/web.rs`).
pub const SEED: u64 = 17;

/// Numbers that are valid JSON but hard on a numerical code.
const HARD_NUMBERS: [f64; 12] = [
    0.0,
    -0.0,
    -1.0,
    1e308,
    -1e308,
    5e-324,
    2.2250738585072014e-308,
    1e-300,
    1e300,
    1e19,
    4503599627370497.0,
    -1e-12,
];

/// Tokens that are not JSON numbers (serde_json refuses them; a JS caller could still send
/// them as strings): put into the text in place of a number.
const BAD_TOKENS: [&str; 7] = [
    "NaN",
    "Infinity",
    "-Infinity",
    "1e400",
    "-1e400",
    "0x10",
    "1.",
];

fn number(rng: &mut ChaCha8Rng) -> Value {
    match rng.random_range(0..10) {
        0..=5 => json!(rng.random_range(-3.0..3.0)),
        6 => json!(HARD_NUMBERS[rng.random_range(0..HARD_NUMBERS.len())]),
        7 => json!(rng.random_range(-5i64..6)),
        _ => json!(rng.random_range(0.0..1.0)),
    }
}

/// A value of the wrong type for a number, a vector or a matrix.
fn wrong_type(rng: &mut ChaCha8Rng) -> Value {
    match rng.random_range(0..7) {
        0 => json!("1.0"),
        1 => Value::Null,
        2 => json!(true),
        3 => json!({"rows": 2}),
        4 => json!([[[1.0]]]),
        5 => json!([]),
        _ => json!(-1),
    }
}

/// A symmetric positive definite `n × n` matrix `A Aᵀ + sI` with a random scale.
fn spd(n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec<f64>> {
    let a: Vec<Vec<f64>> = (0..n)
        .map(|_| (0..n).map(|_| rng.random_range(-1.0..1.0)).collect())
        .collect();
    let shift = [1e-9, 0.1, 1.0][rng.random_range(0..3)];
    let scale = [1e-6, 1.0, 1.0, 1e6][rng.random_range(0..4)];
    (0..n)
        .map(|i| {
            (0..n)
                .map(|j| {
                    let dot: f64 = (0..n).map(|k| a[i][k] * a[j][k]).sum();
                    scale * (dot + if i == j { shift } else { 0.0 })
                })
                .collect()
        })
        .collect()
}

/// A covariance of size about `n`: mostly valid, otherwise broken in one way.
fn matrix(n: usize, rng: &mut ChaCha8Rng) -> Value {
    let m = spd(n, rng);
    match rng.random_range(0..24) {
        0..=15 => json!(m),
        16 => {
            // asymmetric
            let mut m = m;
            if n > 1 {
                m[0][1] += 1.0;
            }
            json!(m)
        }
        17 => {
            // indefinite
            let mut m = m;
            m[0][0] = -m[0][0] - 1.0;
            json!(m)
        }
        18 => {
            // ragged
            let mut m = m;
            m[n - 1].push(1.0);
            json!(m)
        }
        19 => json!(spd(n + 1, rng)),
        20 => {
            let mut v = json!(m);
            v[rng.random_range(0..n)][rng.random_range(0..n)] = number(rng);
            v
        }
        21 => json!(Vec::<Vec<f64>>::new()),
        22 => json!([Vec::<f64>::new()]),
        _ => wrong_type(rng),
    }
}

fn vector(n: usize, rng: &mut ChaCha8Rng) -> Value {
    match rng.random_range(0..10) {
        0..=6 => json!((0..n).map(|_| number(rng)).collect::<Vec<_>>()),
        7 => json!((0..n + 1).map(|_| number(rng)).collect::<Vec<_>>()),
        8 => json!(Vec::<f64>::new()),
        _ => wrong_type(rng),
    }
}

fn pattern(n: usize, rng: &mut ChaCha8Rng) -> Value {
    let p = rng.random_range(0.0..1.0);
    let rows: Vec<Vec<bool>> = (0..n)
        .map(|_| (0..n).map(|_| rng.random_bool(p)).collect())
        .collect();
    match rng.random_range(0..10) {
        0..=7 => json!(rows),
        8 => json!((0..n + 1)
            .map(|_| vec![true; n])
            .collect::<Vec<Vec<bool>>>()),
        _ => wrong_type(rng),
    }
}

/// A setting: in range and small (so a solve stays quick), absurd, negative or the wrong type.
fn setting(rng: &mut ChaCha8Rng, small: impl Fn(&mut ChaCha8Rng) -> Value) -> Value {
    match rng.random_range(0..13) {
        0..=8 => small(rng),
        9 => [
            json!(0),
            json!(-1),
            json!(1e12),
            json!(1e19),
            json!(1e30),
            json!(u64::MAX),
            json!(-1e300),
        ][rng.random_range(0..7)]
        .clone(),
        10 => json!(HARD_NUMBERS[rng.random_range(0..HARD_NUMBERS.len())]),
        11 => json!(0.5),
        _ => wrong_type(rng),
    }
}

fn method(rng: &mut ChaCha8Rng) -> Value {
    match rng.random_range(0..14) {
        0..=10 => json!(RULES[rng.random_range(0..RULES.len())].name),
        11 => json!("CI"),
        12 => json!(""),
        _ => wrong_type(rng),
    }
}

fn nway(n: usize, rng: &mut ChaCha8Rng, object: &mut Map<String, Value>) {
    let k = rng.random_range(0..5);
    let estimates: Vec<Value> = (0..k)
        .map(|_| {
            let m = if rng.random_bool(0.8) { n } else { n + 1 };
            let mut e = Map::new();
            e.insert("p".into(), matrix(m, rng));
            if rng.random_bool(0.5) {
                e.insert("x".into(), vector(m, rng));
            }
            if rng.random_bool(0.05) {
                e.insert("w".into(), json!(1));
            }
            Value::Object(e)
        })
        .collect();
    object.insert("estimates".into(), json!(estimates));
    if rng.random_bool(0.5) {
        let pairs: Vec<Value> = (0..rng.random_range(0..4))
            .map(|_| {
                let j = [json!(rng.random_range(0..k + 2)), json!(-1), json!(1e20)];
                json!({
                    "i": rng.random_range(0..k + 2),
                    "j": j[rng.random_range(0..3)],
                    "pab_unknown": pattern(n, rng),
                })
            })
            .collect();
        object.insert("patterns".into(), json!(pairs));
    }
}

/// A generator of a setting's in-range value.
type Small = fn(&mut ChaCha8Rng) -> Value;

/// Request `index` of the fuzz stream `seed`, as JSON text.
pub fn request(seed: u64, index: u64) -> String {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    let mut o = Map::new();
    let method = method(&mut rng);
    // The solver rules get smaller problems (most cases stay quick).
    let solver = ["sdp", "sdp_cuts", "certified"].contains(&method.as_str().unwrap_or(""));
    let n = if solver {
        [1, 2, 2, 3][rng.random_range(0..4)]
    } else {
        [1, 2, 2, 3, 3, 4][rng.random_range(0..6)]
    };
    if rng.random_bool(0.93) {
        o.insert("method".into(), method);
    }
    if rng.random_bool(0.15) {
        nway(n, &mut rng, &mut o);
        // Sometimes mixed with the two-estimate fields.
        if rng.random_bool(0.1) {
            o.insert("pa".into(), matrix(n, &mut rng));
        }
    } else {
        for (key, p) in [("pa", 0.97), ("pb", 0.97)] {
            if rng.random_bool(p) {
                o.insert(key.into(), matrix(n, &mut rng));
            }
        }
        for key in ["xa", "xb"] {
            if rng.random_bool(0.4) {
                o.insert(key.into(), vector(n, &mut rng));
            }
        }
        if rng.random_bool(0.6) {
            o.insert("pab_unknown".into(), pattern(n, &mut rng));
        }
    }
    let options: [(&str, Small); 7] = [
        ("criterion", |r| {
            json!(["trace", "logdet"][r.random_range(0..2)])
        }),
        ("samples", |r| json!(r.random_range(1..60))),
        ("seed", |r| json!(r.random_range(0..1000))),
        ("max_trials", |r| json!(r.random_range(1..100_000))),
        ("sampler", |r| {
            json!(["rejection", "hit_and_run", "auto"][r.random_range(0..3)])
        }),
        ("time_limit", |r| json!(r.random_range(0.5..5.0))),
        ("level", |r| json!(r.random_range(1..4))),
    ];
    for (key, small) in options {
        if rng.random_bool(0.2) {
            o.insert(key.into(), setting(&mut rng, small));
        }
    }
    if rng.random_bool(0.03) {
        o.insert("unknown_field".into(), json!(1));
    }
    let mut text = Value::Object(o).to_string();
    if rng.random_bool(0.03) {
        // A token that is not a JSON number, in place of the first number.
        if let Some(at) = text.find(|c: char| c.is_ascii_digit()) {
            let end = text[at..]
                .find(|c: char| !(c.is_ascii_digit() || ".eE+-".contains(c)))
                .map_or(text.len(), |e| at + e);
            text.replace_range(at..end, BAD_TOKENS[rng.random_range(0..BAD_TOKENS.len())]);
        }
    }
    if rng.random_bool(0.03) {
        // Truncated (at a character boundary: the text is ASCII).
        let cut = rng.random_range(0..text.len().max(1));
        text.truncate(cut);
    }
    text
}
