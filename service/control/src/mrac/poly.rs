//! Polynomials in the backward shift `q⁻¹`, in the dissertation's convention.
//!
//! A polynomial `P(q⁻¹) = P_0 + P_1 q⁻¹ + … + P_d q⁻ᵈ` is the slice `[P_0, P_1, …, P_d]`
//! (index `i` is the coefficient of `q⁻ⁱ`). As a function of `q` it is
//! `q⁻ᵈ (P_0 qᵈ + P_1 qᵈ⁻¹ + … + P_d)`, so "monic as a function of `q`" means `P_0 = 1`
//! and its roots are those of `P_0 zᵈ + … + P_d` (trailing zero coefficients are not part
//! of the degree). These helpers are for parameter checks and tests; they allocate and are
//! not used in a controller's step.
//!
//! - [`mul`]: the product `A(q⁻¹) B(q⁻¹)`;
//! - [`degree`]: the index of the last nonzero coefficient;
//! - [`is_monic`]: `P_0 = 1`;
//! - [`is_schur_stable`]: every root strictly inside the unit circle (asymptotically
//!   stable), by the Schur–Cohn (Jury) step-down recursion;
//! - [`roots`]: the roots in `q`, as eigenvalues of the companion matrix;
//! - [`min_root_modulus`]: the smallest root modulus (the check of `N_u` in (4.46): roots
//!   of modulus at least 1);
//! - [`divide`]: quotient and remainder of a division in powers of `q⁻¹` aligned at the
//!   highest power (ordinary polynomial division in `q`).

use nalgebra::{Complex, DMatrix};

/// The product `A(q⁻¹) B(q⁻¹)` (length `len(a) + len(b) − 1`; empty if either is).
pub fn mul(a: &[f64], b: &[f64]) -> Vec<f64> {
    if a.is_empty() || b.is_empty() {
        return Vec::new();
    }
    let mut c = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            c[i + j] += x * y;
        }
    }
    c
}

/// The degree: the index of the last nonzero coefficient (0 for a constant or empty
/// polynomial).
pub fn degree(p: &[f64]) -> usize {
    p.iter().rposition(|&c| c != 0.0).unwrap_or(0)
}

/// `P_0 = 1` (monic as a function of `q`).
pub fn is_monic(p: &[f64]) -> bool {
    p.first() == Some(&1.0)
}

/// True when the monic polynomial `p` (`p[0] = 1`, finite coefficients) is asymptotically
/// stable as a function of `q`: every root of `zᵈ + p_1 zᵈ⁻¹ + … + p_d` has modulus `< 1`.
///
/// Schur–Cohn step-down (the Levinson recursion run backwards): with `a = p` of degree
/// `m`, the reflection coefficient is `k_m = a_m`; the polynomial is stable iff `|k_m| < 1`
/// and the reduced `a'_j = (a_j − k_m a_{m−j}) / (1 − k_m²)`, `j < m`, is stable. A
/// constant is stable. Returns false for a non-monic or non-finite `p`.
pub fn is_schur_stable(p: &[f64]) -> bool {
    if !is_monic(p) || p.iter().any(|c| !c.is_finite()) {
        return false;
    }
    let mut a: Vec<f64> = p[..=degree(p)].to_vec();
    let mut next = a.clone();
    for m in (1..a.len()).rev() {
        let k = a[m];
        if k.is_nan() || k.abs() >= 1.0 {
            return false;
        }
        let den = 1.0 - k * k;
        for j in 0..m {
            next[j] = (a[j] - k * a[m - j]) / den;
        }
        a[..m].copy_from_slice(&next[..m]);
    }
    true
}

/// The roots in `q` of `p` (those of `p_0 zᵈ + … + p_d`, `d` = [`degree`]), as the
/// eigenvalues of the companion matrix; empty for a constant or when `p_0 = 0`.
pub fn roots(p: &[f64]) -> Vec<Complex<f64>> {
    let d = degree(p);
    let lead = p.first().copied().unwrap_or(0.0);
    if d == 0 || lead == 0.0 {
        return Vec::new();
    }
    let mut c = DMatrix::zeros(d, d);
    for j in 0..d {
        c[(0, j)] = -p[j + 1] / lead;
    }
    for i in 1..d {
        c[(i, i - 1)] = 1.0;
    }
    c.complex_eigenvalues().iter().copied().collect()
}

/// The smallest modulus of the roots of `p` in `q` (`+∞` for a constant).
pub fn min_root_modulus(p: &[f64]) -> f64 {
    roots(p)
        .iter()
        .map(|z| z.norm())
        .fold(f64::INFINITY, f64::min)
}

/// Division of `num` by `den` with the coefficients taken from index 0 on (as polynomials
/// in `q` padded to their slice lengths): returns `(quotient, remainder)` with
/// `num = mul(den, quotient) + remainder` coefficient by coefficient, `quotient` of
/// length `len(num) − len(den) + 1` and `remainder` of length `len(num)` whose first
/// `len(quotient)` entries are zero. `den` divides `num` exactly when the remainder is
/// zero. Needs `den[0] ≠ 0` and `len(num) ≥ len(den)`; otherwise the quotient is empty
/// and the remainder is `num`.
pub fn divide(num: &[f64], den: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let a = num.len();
    let b = den.len();
    if b == 0 || a < b || den[0] == 0.0 {
        return (Vec::new(), num.to_vec());
    }
    let mut rem = num.to_vec();
    let mut quot = vec![0.0; a - b + 1];
    for i in 0..quot.len() {
        let c = rem[i] / den[0];
        quot[i] = c;
        for (j, d) in den.iter().enumerate() {
            rem[i + j] -= c * d;
        }
        rem[i] = 0.0;
    }
    (quot, rem)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_and_degrees_follow_the_q_inverse_convention() {
        // (1 − 0.5 q⁻¹)(1 + 0.5 q⁻¹) = 1 − 0.25 q⁻² (4.86).
        assert_eq!(mul(&[1.0, -0.5], &[1.0, 0.5]), vec![1.0, 0.0, -0.25]);
        assert_eq!(degree(&[1.0, 0.0, -0.25, 0.0]), 2);
        assert_eq!(degree(&[0.0]), 0);
        assert!(is_monic(&[1.0, 3.0]) && !is_monic(&[2.0, 1.0]) && !is_monic(&[]));
    }

    #[test]
    fn the_schur_cohn_test_agrees_with_the_root_moduli() {
        let cases: [&[f64]; 8] = [
            &[1.0],
            &[1.0, 0.5],
            &[1.0, -1.0],
            &[1.0, 0.0, 0.25],
            &[1.0, 0.0, -0.25],
            &[1.0, -1.5],
            &[1.0, -1.8, 0.81],
            &[1.0, -0.5, 0.3, -0.9, 0.2],
        ];
        for p in cases {
            let by_roots = roots(p).iter().all(|z| z.norm() < 1.0 - 1e-12);
            assert_eq!(is_schur_stable(p), by_roots, "{p:?}");
        }
        assert!(!is_schur_stable(&[2.0, 0.1]));
        assert!(!is_schur_stable(&[1.0, f64::NAN]));
        assert!((min_root_modulus(&[1.0, -1.5]) - 1.5).abs() < 1e-12);
        assert_eq!(min_root_modulus(&[1.0]), f64::INFINITY);
    }

    #[test]
    fn division_recovers_a_factor() {
        let n = mul(&[0.0, 1.0], &[1.0, -0.5]); // q⁻¹ − 0.5 q⁻²
        let (q, r) = divide(&[1.0, -0.5], &[1.0]);
        assert_eq!(q, vec![1.0, -0.5]);
        assert!(r.iter().all(|&c| c == 0.0));
        let (q, r) = divide(&n[1..], &[1.0, -0.5]);
        assert_eq!(q, vec![1.0]);
        assert!(r.iter().all(|&c| c.abs() < 1e-15));
        let (_, r) = divide(&[1.0, 0.2, 0.3], &[1.0, -1.5]);
        assert!(r.iter().any(|&c| c.abs() > 1e-3));
    }
}
