//! The cones of directions of the sector and cone families: their multipliers, exact in integers
//! (the covering argument is the parent's module docs, "Sectors").

use nalgebra::DMatrix;

use crate::error::SolveError;

/// Most sectors accepted (`CertifySettings::sectors`).
pub const MAX_SECTORS: u32 = 64;

/// The sectors' multipliers: integer directions `d_k ≈ 2⁶ (cos πk/S, sin πk/S)`,
/// `k = 0..S`, with `d_S = −d_0`, and for each sector `q(v) = det(d_k, v)·det(v, d_{k+1})`
/// by its coefficients on `v₁², v₁v₂, v₂²` (integers below `2¹⁴` times `2⁻¹²`, exact). Consecutive directions are
/// checked to turn counterclockwise within the closed upper half-plane, exactly in
/// integers — the covering argument of the module docs needs nothing else.
pub(crate) fn sector_multipliers(count: u32) -> Result<Vec<[f64; 3]>, SolveError> {
    let radius = 64.0;
    let s = count as usize;
    let mut d: Vec<[i64; 2]> = (0..=s)
        .map(|k| {
            let t = std::f64::consts::PI * k as f64 / count as f64;
            [
                (radius * t.cos()).round() as i64,
                (radius * t.sin()).round() as i64,
            ]
        })
        .collect();
    d[0] = [64, 0];
    d[s] = [-64, 0];
    let turns = d
        .windows(2)
        .all(|w| w[0][1] >= 0 && w[1][1] >= 0 && w[0][0] * w[1][1] - w[0][1] * w[1][0] > 0);
    if count < 2 || !turns {
        return Err(SolveError::InvalidSettings(format!(
            "sectors must be in 2..={MAX_SECTORS} (got {count})"
        )));
    }
    Ok(d.windows(2)
        .map(|w| {
            let ([x0, y0], [x1, y1]) = (w[0], w[1]);
            // (x0 v₂ − y0 v₁)(y1 v₁ − x1 v₂) / 2¹²: integers below 2¹⁴ times a power of two,
            // exact, and of order one (the solver needs a well-scaled program).
            let scale = 1.0 / (radius * radius);
            [
                (-y0 * y1) as f64 * scale,
                (x0 * y1 + y0 * x1) as f64 * scale,
                (-x0 * x1) as f64 * scale,
            ]
        })
        .collect())
}

/// The multipliers of each piece of directions (module docs, "Sectors"): for two states one
/// per sector of [`sector_multipliers`]; for three states, `count` ∈ {4, 16, 64} cones
/// spanned by integer generators — the four octants of `v₃ ≥ 0`, each split 0, 1 or 2 times
/// into four at its edges' midpoints (the generators `u_i + u_j`), an exact subdivision of the
/// octant — with the three products `q_ij(v) = (n_i·v)(n_j·v)`, `i < j`, of the cone's facet
/// normals `n_i = u_j × u_k`: on the cone all `n_i·v` share a sign (`n_i·v = λ_i det U` for
/// `v = Σ λ_i u_i`), so every `q_ij ≥ 0` there and on its negative, and the octants and their
/// negatives cover space. Each matrix is scaled by a power of two to entries of order one
/// (exact).
#[allow(non_snake_case)]
pub(crate) fn cone_multipliers(n: usize, count: u32) -> Result<Vec<Vec<DMatrix<f64>>>, SolveError> {
    match n {
        2 => Ok(sector_multipliers(count)?
            .into_iter()
            .map(|sigma| {
                vec![DMatrix::from_row_slice(
                    2,
                    2,
                    &[sigma[0], 0.5 * sigma[1], 0.5 * sigma[1], sigma[2]],
                )]
            })
            .collect()),
        3 => Ok(cone_generators(count)?.iter().map(cone_piece).collect()),
        _ => Err(SolveError::InvalidSettings(format!(
            "cones of directions certify blocks of two or three states (got a block of {n})"
        ))),
    }
}

/// The multipliers of the cone spanned by the integer generators `u` (three states; see
/// [`cone_multipliers`]): the products `q_ij(v) = (n_i·v)(n_j·v)`, `i < j`, of its facet
/// normals `n_i = u_j × u_k`, each matrix scaled by a power of two to entries of order one
/// (exact: [`bisect`] keeps the generators below `2¹²`, so the normals stay below `2²⁵` and
/// the entries of `2 S` below `2⁵¹`).
#[allow(non_snake_case)]
pub(crate) fn cone_piece(u: &[[i64; 3]; 3]) -> Vec<DMatrix<f64>> {
    let normals = [cross(u[1], u[2]), cross(u[2], u[0]), cross(u[0], u[1])];
    [(0, 1), (0, 2), (1, 2)]
        .iter()
        .map(|&(i, j)| {
            let (a, b) = (normals[i], normals[j]);
            // 2 S = a bᵀ + b aᵀ in integers, then scaled by a power of two.
            let twice: Vec<i64> = (0..9)
                .map(|e| a[e / 3] * b[e % 3] + b[e / 3] * a[e % 3])
                .collect();
            let largest = twice.iter().map(|v| v.abs()).max().unwrap_or(1).max(1);
            let scale = 0.5 / (largest as f64).log2().ceil().exp2();
            DMatrix::from_iterator(3, 3, twice.iter().map(|&v| v as f64 * scale))
        })
        .collect()
}

/// `a × b` in integers.
pub(super) fn cross(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The cone spanned by `u` cut in two at the midpoint of its widest edge (the largest angle
/// between two generators): `[u_i, u_i + u_j, u_k]` and `[u_i + u_j, u_j, u_k]`. An exact
/// subdivision: `v = λ_i u_i + λ_j u_j + λ_k u_k` with `λ ≥ 0` is
/// `(λ_i − λ_j) u_i + λ_j (u_i + u_j) + λ_k u_k` when `λ_i ≥ λ_j`, else
/// `(λ_j − λ_i) u_j + λ_i (u_i + u_j) + λ_k u_k`, in the first or the second cone; so a cover
/// of space by cones and their negatives stays one. `None` when the new generator's entries
/// would leave the range in which [`cone_piece`]'s multipliers are exact (`|u_i| < 2¹²`).
pub(crate) fn bisect(u: &[[i64; 3]; 3]) -> Option<[[[i64; 3]; 3]; 2]> {
    let angle = |a: [i64; 3], b: [i64; 3]| {
        let f = |v: [i64; 3]| v.map(|x| x as f64);
        let (a, b) = (f(a), f(b));
        let dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        (dot / (norm(a) * norm(b))).clamp(-1.0, 1.0).acos()
    };
    let (i, j) = [(0, 1), (1, 2), (0, 2)]
        .into_iter()
        .max_by(|&(a, b), &(c, d)| angle(u[a], u[b]).total_cmp(&angle(u[c], u[d])))?;
    let mid = [u[i][0] + u[j][0], u[i][1] + u[j][1], u[i][2] + u[j][2]];
    if mid.iter().any(|x| x.abs() >= 1 << 12) {
        return None;
    }
    // Each child keeps the parent's orientation (generator order), so its normals point
    // the same way.
    let mut first = *u;
    first[j] = mid;
    let mut second = *u;
    second[i] = mid;
    Some([first, second])
}

/// The integer generators of the cones of [`cone_multipliers`] for three states.
pub(crate) fn cone_generators(count: u32) -> Result<Vec<[[i64; 3]; 3]>, SolveError> {
    let splits = match count {
        4 => 0,
        16 => 1,
        64 => 2,
        _ => {
            return Err(SolveError::InvalidSettings(format!(
                "three-state blocks are certified on 4, 16 or 64 cones (got {count})"
            )))
        }
    };
    let mut cones: Vec<[[i64; 3]; 3]> = [(1, 1), (-1, 1), (-1, -1), (1, -1)]
        .iter()
        .map(|&(x, y)| [[x, 0, 0], [0, y, 0], [0, 0, 1]])
        .collect();
    let add = |a: [i64; 3], b: [i64; 3]| [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    for _ in 0..splits {
        cones = cones
            .iter()
            .flat_map(|&[u1, u2, u3]| {
                let (m12, m13, m23) = (add(u1, u2), add(u1, u3), add(u2, u3));
                [
                    [u1, m12, m13],
                    [u2, m12, m23],
                    [u3, m13, m23],
                    [m12, m23, m13],
                ]
            })
            .collect();
    }
    Ok(cones)
}
