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

/// A cone of directions in `ℝᴺ`: the non-negative combinations of `N` integer generators
/// (rows), linearly independent.
pub(crate) type Cone<const N: usize> = [[i64; N]; N];

/// Generators' entries stay below this in absolute value (three or four states; none
/// otherwise), so that [`cone_piece`]'s multipliers are exact: the facet normals are
/// `(N − 1) × (N − 1)` minors, below `2²⁵` for three states (generators below `2¹²`; `2·2²⁴`
/// for a 2 × 2 minor) and below `6·2²¹ < 2²⁴` for four (generators below `2⁷`; `3!` terms
/// of `2²¹`), so the integer entries of `2 S = a bᵀ + b aᵀ` stay below `2⁵¹` and `2⁴⁹`.
pub(crate) const fn generator_limit(n: usize) -> i64 {
    match n {
        3 => 1 << 12,
        4 => 1 << 7,
        _ => 0,
    }
}

/// The facet normals of the cone spanned by `u`: `n_i[c] = det U` with row `i` replaced by
/// `e_c`, so `n_i·v = det U` with row `i` replaced by `v`. For `v = Σ_k λ_k u_k` that is
/// `λ_i det U` (multilinearity; the other rows repeat), so on the cone and its negative all
/// `n_i·v` share a sign, and `n_i·u_j = δ_ij det U`. For three states `n_i = u_j × u_k`
/// (`i, j, k` cyclic).
pub(crate) fn facet_normals<const N: usize>(u: &Cone<N>) -> [[i64; N]; N] {
    std::array::from_fn(|i| {
        std::array::from_fn(|c| {
            let rows: Vec<Vec<i128>> = (0..N)
                .map(|r| {
                    (0..N)
                        .map(|k| match r == i {
                            true => i128::from(k == c),
                            false => i128::from(u[r][k]),
                        })
                        .collect()
                })
                .collect();
            i64::try_from(determinant(&rows)).expect("generators below generator_limit")
        })
    })
}

/// `det` of a small square integer matrix, exactly (Laplace expansion along the first row).
fn determinant(rows: &[Vec<i128>]) -> i128 {
    match rows.len() {
        0 => 1,
        1 => rows[0][0],
        m => (0..m)
            .filter(|&c| rows[0][c] != 0)
            .map(|c| {
                let minor: Vec<Vec<i128>> = rows[1..]
                    .iter()
                    .map(|r| (0..m).filter(|&k| k != c).map(|k| r[k]).collect())
                    .collect();
                let sign = if c % 2 == 0 { 1 } else { -1 };
                sign * rows[0][c] * determinant(&minor)
            })
            .sum(),
    }
}

/// The pairs `(i, j)`, `i < j`, of `N` generators or normals, nearest first: `(0, 1), (1, 2),
/// …, (0, 2), …` (the order in which [`bisect`] breaks ties between equally wide edges).
fn pairs(n: usize) -> impl Iterator<Item = (usize, usize)> {
    (1..n).flat_map(move |gap| (0..n - gap).map(move |i| (i, i + gap)))
}

/// The multipliers of the cone spanned by the integer generators `u` (three or four states;
/// see [`cone_multipliers`]): the products `q_ij(v) = (n_i·v)(n_j·v)`, `i < j` in
/// lexicographic order, of its facet normals ([`facet_normals`]), each matrix scaled by a
/// power of two to entries of order one (exact while the generators stay below
/// [`generator_limit`], which [`bisect`] keeps).
#[allow(non_snake_case)]
pub(crate) fn cone_piece<const N: usize>(u: &Cone<N>) -> Vec<DMatrix<f64>> {
    let normals = facet_normals(u);
    let mut ordered: Vec<(usize, usize)> = pairs(N).collect();
    ordered.sort_unstable();
    ordered
        .into_iter()
        .map(|(i, j)| {
            let (a, b) = (normals[i], normals[j]);
            // 2 S = a bᵀ + b aᵀ in integers, then scaled by a power of two.
            let twice: Vec<i64> = (0..N * N)
                .map(|e| a[e / N] * b[e % N] + b[e / N] * a[e % N])
                .collect();
            let largest = twice.iter().map(|v| v.abs()).max().unwrap_or(1).max(1);
            let scale = 0.5 / (largest as f64).log2().ceil().exp2();
            DMatrix::from_iterator(N, N, twice.iter().map(|&v| v as f64 * scale))
        })
        .collect()
}

/// `a × b` in integers.
#[cfg(test)]
pub(super) fn cross(a: [i64; 3], b: [i64; 3]) -> [i64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The cone spanned by `u` cut in two at the midpoint of its widest edge (the largest angle
/// between two generators; ties to the last in [`pairs`]' order): `u_i` replaced by
/// `u_i + u_j` in one half, `u_j` in the other. An exact subdivision:
/// `v = Σ_k λ_k u_k` with `λ ≥ 0` is `(λ_i − λ_j) u_i + λ_j (u_i + u_j) + …` when
/// `λ_i ≥ λ_j`, else `(λ_j − λ_i) u_j + λ_i (u_i + u_j) + …`, in the first or the second
/// cone; so a cover of space by cones and their negatives stays one. `None` when the new
/// generator's entries would reach [`generator_limit`], beyond which [`cone_piece`]'s
/// multipliers are not exact.
pub(crate) fn bisect<const N: usize>(u: &Cone<N>) -> Option<[Cone<N>; 2]> {
    let angle = |a: [i64; N], b: [i64; N]| {
        let (a, b) = (a.map(|x| x as f64), b.map(|x| x as f64));
        let dot = |x: &[f64; N], y: &[f64; N]| x.iter().zip(y).map(|(p, q)| p * q).sum::<f64>();
        (dot(&a, &b) / (dot(&a, &a).sqrt() * dot(&b, &b).sqrt()))
            .clamp(-1.0, 1.0)
            .acos()
    };
    let (i, j) =
        pairs(N).max_by(|&(a, b), &(c, d)| angle(u[a], u[b]).total_cmp(&angle(u[c], u[d])))?;
    let mid: [i64; N] = std::array::from_fn(|e| u[i][e] + u[j][e]);
    if mid.iter().any(|x| x.abs() >= generator_limit(N)) {
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

/// The `2^{N−1}` orthants of the half-space `v_N ≥ 0`, spanned by `±e_1, …, ±e_{N−1}, e_N`
/// (signs in Gray-code order): every `v` with `v_N ≥ 0` lies in the one of its signs, so
/// they and their negatives cover space.
pub(crate) fn orthants<const N: usize>() -> Vec<Cone<N>> {
    (0..1usize << (N - 1))
        .map(|k| {
            let gray = k ^ (k >> 1);
            std::array::from_fn(|r| {
                std::array::from_fn(|c| match (r == c, r + 1 < N && gray >> r & 1 == 1) {
                    (false, _) => 0,
                    (true, true) => -1,
                    (true, false) => 1,
                })
            })
        })
        .collect()
}

/// The integer generators of the cones of [`cone_multipliers`] for three states.
pub(crate) fn cone_generators(count: u32) -> Result<Vec<Cone<3>>, SolveError> {
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
    let mut cones: Vec<Cone<3>> = orthants();
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
