//! The monomial layout of a certificate of level `r`: exponent vectors, multinomial weights and
//! where each product lands in the program.

use std::collections::HashMap;

use nalgebra::DMatrix;

pub(super) fn binomial(n: usize, k: usize) -> usize {
    (0..k).fold(1, |acc, i| acc * (n - i) / (i + 1))
}

/// The exponent vectors of degree `d` in `n` variables (graded, lexicographic).
pub(super) fn monomials(n: usize, d: usize) -> Vec<Vec<usize>> {
    pub(super) fn rec(n: usize, d: usize, prefix: &mut Vec<usize>, out: &mut Vec<Vec<usize>>) {
        if prefix.len() == n - 1 {
            prefix.push(d);
            out.push(prefix.clone());
            prefix.pop();
            return;
        }
        for e in (0..=d).rev() {
            prefix.push(e);
            rec(n, d - e, prefix, out);
            prefix.pop();
        }
    }
    let mut out = Vec::new();
    rec(n, d, &mut Vec::with_capacity(n), &mut out);
    out
}

/// `d! / β!` for an exponent vector `β` of degree `d`.
pub(super) fn multinomial(beta: &[usize]) -> f64 {
    let mut num = 1.0;
    let mut k = 0;
    for &b in beta {
        for i in 1..=b {
            k += 1;
            num = num * k as f64 / i as f64;
        }
    }
    num.round()
}

/// The index layout of one block's level-`r` program.
pub(super) struct Layout {
    pub(super) n: usize,
    /// Rows of `Kᵀ`: `2n`.
    pub(super) m: usize,
    /// Degree-`r` monomials (`s` of them).
    pub(super) mons: Vec<Vec<usize>>,
    /// Degree-`(r − 1)` monomials and their multinomial coefficients.
    pub(super) lower: Vec<(Vec<usize>, f64)>,
    /// Degree-`2r` monomials, by exponent.
    pub(super) products: HashMap<Vec<usize>, usize>,
    /// `α + β` as an index of `products`, for `α`, `β` indices of `mons`.
    pub(super) sum: Vec<Vec<usize>>,
}

impl Layout {
    pub(super) fn new(n: usize, r: usize) -> Self {
        let mons = monomials(n, r);
        let lower = monomials(n, r - 1)
            .into_iter()
            .map(|b| {
                let c = multinomial(&b);
                (b, c)
            })
            .collect();
        let products: HashMap<Vec<usize>, usize> = monomials(n, 2 * r)
            .into_iter()
            .enumerate()
            .map(|(i, g)| (g, i))
            .collect();
        let add =
            |a: &[usize], b: &[usize]| a.iter().zip(b).map(|(x, y)| x + y).collect::<Vec<_>>();
        let sum = mons
            .iter()
            .map(|a| mons.iter().map(|b| products[&add(a, b)]).collect())
            .collect();
        Self {
            n,
            m: 2 * n,
            mons,
            lower,
            products,
            sum,
        }
    }

    /// Size of `C`.
    pub(super) fn big(&self) -> usize {
        self.m * self.mons.len()
    }

    /// The monomial index `k` with `α = β + e_k`, if any.
    pub(super) fn step(&self, alpha: usize, beta: &[usize]) -> Option<usize> {
        let a = &self.mons[alpha];
        let mut k = None;
        for i in 0..self.n {
            match a[i] as isize - beta[i] as isize {
                0 => {}
                1 if k.is_none() => k = Some(i),
                _ => return None,
            }
        }
        k
    }

    /// A multiplier's coefficient on the monomial of index `g` in `products` (level 1):
    /// `q(v) = vᵀ S v` has `S_kk` on `v_k²` and `2 S_kl` on `v_k v_l` (exact: `S` holds
    /// multiples of a power of two with room to spare).
    #[allow(non_snake_case)]
    pub(super) fn multiplier_coefficient(&self, S: &DMatrix<f64>, g: usize) -> f64 {
        let e = self
            .products
            .iter()
            .find(|(_, &i)| i == g)
            .map(|(e, _)| e)
            .expect("a degree-2 monomial");
        let ones: Vec<usize> = (0..self.n).filter(|&k| e[k] > 0).collect();
        match ones.as_slice() {
            [k] => S[(*k, *k)],
            [k, l] => 2.0 * S[(*k, *l)],
            _ => unreachable!("a degree-2 monomial has one or two variables"),
        }
    }

    /// Index in `products` of `2β + e_k + e_l`.
    pub(super) fn quad(&self, beta: &[usize], k: usize, l: usize) -> usize {
        let mut g: Vec<usize> = beta.iter().map(|b| 2 * b).collect();
        g[k] += 1;
        g[l] += 1;
        self.products[&g]
    }
}
