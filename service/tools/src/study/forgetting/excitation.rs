//! How much the input excites the estimator over a stretch of steps: the singular values of
//! the regressor matrix `Φ = [φ_k; φ_{k+1}; …]` stacked from the rows
//! `φ_k = [y_{k−1} y_{k−2} u_k u_{k−1} u_{k−2}]` of §5.3 (the regressor below (5.8)).
//!
//! RLS identifies `θ` from these rows; once forgetting has discounted the data before the
//! change (Algorithm 1), how fast the new parameters are pinned down depends on how well the
//! rows after the change span `ℝ⁵`. The smallest singular value `σ_min(Φ)` measures the
//! direction that is excited least, `σ_max/σ_min` (the condition number) how unevenly.
//! The singular values are the square roots of the eigenvalues of the Gram matrix `ΦᵀΦ`,
//! computed here by cyclic Jacobi rotations.

use crate::study::forgetting::experiment::N;

/// The singular values of a stretch of regressor rows and the input's RMS there.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Excitation {
    /// Smallest singular value `σ_min(Φ)`.
    pub sigma_min: f64,
    /// Largest singular value `σ_max(Φ)`.
    pub sigma_max: f64,
    /// RMS of the input `u_k` over the rows (their third component).
    pub input_rms: f64,
}

impl Excitation {
    /// The excitation of `rows` (`None` when there are none or a value is not finite).
    pub fn of(rows: &[[f64; N]]) -> Option<Self> {
        if rows.is_empty() || rows.iter().flatten().any(|v| !v.is_finite()) {
            return None;
        }
        let mut gram = [[0.0; N]; N];
        for r in rows {
            for (g, ri) in gram.iter_mut().zip(r) {
                for (gij, rj) in g.iter_mut().zip(r) {
                    *gij += ri * rj;
                }
            }
        }
        let eig = symmetric_eigenvalues(gram);
        let lo = eig.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = eig.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let input_rms = (rows.iter().map(|r| r[2] * r[2]).sum::<f64>() / rows.len() as f64).sqrt();
        // Round-off can leave a zero eigenvalue slightly negative.
        Some(Self {
            sigma_min: lo.max(0.0).sqrt(),
            sigma_max: hi.max(0.0).sqrt(),
            input_rms,
        })
    }

    /// The condition number `σ_max/σ_min` (`+∞` when `σ_min = 0`).
    pub fn condition(&self) -> f64 {
        if self.sigma_min > 0.0 {
            self.sigma_max / self.sigma_min
        } else {
            f64::INFINITY
        }
    }
}

/// The eigenvalues of the symmetric matrix `a` (unordered), by cyclic Jacobi rotations
/// until the off-diagonal part is negligible against the diagonal.
fn symmetric_eigenvalues(mut a: [[f64; N]; N]) -> [f64; N] {
    for _sweep in 0..100 {
        let off: f64 = (0..N)
            .flat_map(|i| (0..N).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i][j] * a[i][j])
            .sum();
        let diag: f64 = (0..N).map(|i| a[i][i] * a[i][i]).sum();
        if off <= 1e-30 * diag.max(f64::MIN_POSITIVE) {
            break;
        }
        for p in 0..N {
            for q in p + 1..N {
                if a[p][q] == 0.0 {
                    continue;
                }
                // The rotation that zeroes a[p][q]: tan(2φ) = 2 a_pq / (a_qq − a_pp).
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for row in a.iter_mut() {
                    let (akp, akq) = (row[p], row[q]);
                    row[p] = c * akp - s * akq;
                    row[q] = s * akp + c * akq;
                }
                let (rp, rq) = (a[p], a[q]);
                for (k, (apk, aqk)) in rp.iter().zip(&rq).enumerate() {
                    a[p][k] = c * apk - s * aqk;
                    a[q][k] = s * apk + c * aqk;
                }
            }
        }
    }
    std::array::from_fn(|i| a[i][i])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scaled_unit_rows_have_their_scales_as_singular_values() {
        let scales = [3.0, 0.5, 2.0, 1.0, 4.0];
        let rows: Vec<[f64; N]> = (0..N)
            .map(|i| std::array::from_fn(|j| if i == j { scales[i] } else { 0.0 }))
            .collect();
        let e = Excitation::of(&rows).unwrap();
        assert!((e.sigma_min - 0.5).abs() < 1e-12, "{e:?}");
        assert!((e.sigma_max - 4.0).abs() < 1e-12, "{e:?}");
        assert!((e.condition() - 8.0).abs() < 1e-10);
        // u_k is the third component: 2 in one row of five.
        assert!((e.input_rms - (4.0f64 / 5.0).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn a_known_gram_matrix_gives_its_eigenvalues() {
        // Rows [1 1 0 0 0] and [1 −1 0 0 0] scaled: ΦᵀΦ = diag(2, 2, …) in the first block
        // rotated by 45°; with rows [a a 0 0 0], [b −b 0 0 0] the Gram block is
        // [[a²+b², a²−b²], [a²−b², a²+b²]] with eigenvalues 2a², 2b².
        let (a, b) = (2.0, 0.5);
        let rows = [
            [a, a, 0.0, 0.0, 0.0],
            [b, -b, 0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 0.0, 1.0],
        ];
        let e = Excitation::of(&rows).unwrap();
        assert!((e.sigma_min - (2.0 * b * b).sqrt()).abs() < 1e-12, "{e:?}");
        assert!((e.sigma_max - (2.0 * a * a).sqrt()).abs() < 1e-12, "{e:?}");
        let mut eig = symmetric_eigenvalues([
            [4.0, 1.0, 0.0, 0.0, 0.0],
            [1.0, 3.0, 1.0, 0.0, 0.0],
            [0.0, 1.0, 2.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 0.0, 5.0],
        ]);
        eig.sort_by(f64::total_cmp);
        // The tridiagonal block [[4,1,0],[1,3,1],[0,1,2]] has eigenvalues 3 and 3 ± √3.
        let mut want = [1.0, 3.0 - 3f64.sqrt(), 3.0, 3.0 + 3f64.sqrt(), 5.0];
        want.sort_by(f64::total_cmp);
        for (g, w) in eig.iter().zip(want) {
            assert!((g - w).abs() < 1e-10, "{eig:?}");
        }
    }

    #[test]
    fn rank_deficient_rows_have_zero_excitation_and_bad_input_none() {
        // Fewer rows than parameters: σ_min = 0, condition +∞.
        let rows = [[1.0, 2.0, 3.0, 4.0, 5.0], [0.0, 1.0, 0.0, 1.0, 0.0]];
        let e = Excitation::of(&rows).unwrap();
        assert!(e.sigma_min < 1e-6, "{e:?}");
        assert!(e.condition() > 1e6);
        assert_eq!(Excitation::of(&[]), None);
        assert_eq!(Excitation::of(&[[f64::NAN, 0.0, 0.0, 0.0, 0.0]]), None);
    }
}
