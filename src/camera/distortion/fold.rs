//! The fold radius of a lens ([module docs](super)): the first positive zero of a polynomial in `s = r²` (the radial
//! slope's numerator, the rational denominator), by recursion on the derivatives and bisection on monotone pieces.

/// A polynomial `c[0] + c[1] s + … + c[6] s⁶` in `s = r²`.
type Polynomial = [f64; 7];

fn value(p: &Polynomial, s: f64) -> f64 {
    p.iter().rev().fold(0.0, |acc, &c| acc * s + c)
}

fn derivative(p: &Polynomial) -> Polynomial {
    let mut d = [0.0; 7];
    for (i, c) in p.iter().enumerate().skip(1) {
        d[i - 1] = i as f64 * c;
    }
    d
}

/// The product of two cubics.
fn product(a: &[f64; 4], b: &[f64; 4]) -> Polynomial {
    let mut p = [0.0; 7];
    for (i, ai) in a.iter().enumerate() {
        for (j, bj) in b.iter().enumerate() {
            p[i + j] += ai * bj;
        }
    }
    p
}

/// Points of `(0, ∞)` in increasing order, at most 6 (a polynomial's degree).
#[derive(Default)]
struct Crossings {
    at: [f64; 6],
    len: usize,
}

impl Crossings {
    fn as_slice(&self) -> &[f64] {
        &self.at[..self.len]
    }
}

/// The points of `(0, ∞)` where `p(s) > 0` turns from true to false or back, in increasing order. Between two
/// consecutive crossings of `p′` (and `0`, `∞`) `p` is monotone, so the test flips at most once there, where bisection
/// finds it: a recursion on the derivative down to a constant. A point where `p` (or `p′`) only touches 0 may be listed
/// twice, which leaves the pieces between crossings monotone.
fn crossings(p: &Polynomial) -> Crossings {
    let mut found = Crossings::default();
    if p[1..].iter().all(|&c| c == 0.0) {
        return found;
    }
    let pieces = crossings(&derivative(p));
    let mut low = 0.0;
    for high in pieces.as_slice().iter().copied().chain([f64::INFINITY]) {
        if let (Some(root), Some(slot)) = (
            crossing_on_monotone_piece(p, low, high),
            found.at.get_mut(found.len),
        ) {
            *slot = root;
            found.len += 1;
        }
        low = high;
    }
    found
}

/// The point of `(low, high]` where `p(s) > 0` flips, `p` monotone there, if any; to the resolution of `f64`, on the
/// flipped side. An infinite `high` stands for the largest `f64`: a flip past it is none, and a crossing of `p′` past it
/// is no end of a monotone piece either (a lens with a subnormal `k2` has its slope's critical points near 1e318,
/// found by the fuzz harness: the sign "at ∞" of the leading coefficient is not the sign at the largest `f64`).
fn crossing_on_monotone_piece(p: &Polynomial, low: f64, high: f64) -> Option<f64> {
    // Horner's evaluation at the largest f64 overflows to ±∞ with the sign of the value, never to NaN.
    let above = |s: f64| value(p, s) > 0.0;
    let start = above(low);
    let mut high = high.min(f64::MAX);
    if above(high) == start {
        return None;
    }
    // A bracket as wide as 1e308 needs about 1 100 halvings (a lens with a tiny k2 has its slope's critical point
    // there, found by the fuzz harness); the cap only guards the loop. Halves, then sum: no overflow near f64::MAX.
    let mut low = low;
    for _ in 0..2_200 {
        let middle = 0.5 * low + 0.5 * high;
        if middle <= low || middle >= high {
            break;
        }
        if above(middle) == start {
            low = middle;
        } else {
            high = middle;
        }
    }
    Some(high)
}

/// `r_f²` (module docs): the first `s > 0` where the radial slope's numerator `P(s)` or the denominator `M(s)`
/// reaches 0, `∞` when neither does. Both are 1 at `s = 0`.
pub(super) fn fold_r2(all: &[f64; 12]) -> f64 {
    let [k1, k2, _, _, k3, k4, k5, k6, ..] = *all;
    let numerator = [1.0, k1, k2, k3];
    let denominator = [1.0, k4, k5, k6];
    let numerator_slope = [k1, 2.0 * k2, 3.0 * k3, 0.0];
    let denominator_slope = [k4, 2.0 * k5, 3.0 * k6, 0.0];
    let (nm, n_m, nm_) = (
        product(&numerator, &denominator),
        product(&numerator_slope, &denominator),
        product(&numerator, &denominator_slope),
    );
    let mut slope = nm;
    for i in 0..6 {
        slope[i + 1] += 2.0 * (n_m[i] - nm_[i]);
    }
    let mut pole = [0.0; 7];
    pole[..4].copy_from_slice(&denominator);
    let first = |p: &Polynomial| crossings(p).as_slice().first().copied();
    [first(&slope), first(&pole)]
        .into_iter()
        .flatten()
        .fold(f64::INFINITY, f64::min)
}
