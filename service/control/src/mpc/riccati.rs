//! # riccati: the unconstrained minimizer of PCAC's receding-horizon cost by a Riccati
//! recursion
//!
//! ## The problem (section 2.3.2.2 of the dissertation)
//!
//! Without its constraints (2.49)–(2.51), the receding-horizon problem (2.48) is a
//! strictly convex quadratic in `U` ([`super::condense`] condenses it into
//! `½ Uᵀ H U + fᵀ U + c`, whose minimizer is `U* = −H⁻¹ f`). Written with the
//! realization (2.36)–(2.42) instead of the prediction (2.43)–(2.46), and the steps
//! numbered `i = 0 … ℓ−1` as in the code (`x_0 = x_{1|k}`, `u_i = u_{i+1|k}`,
//! `y_i = y_{i+1|k}`, `u_{−1} = u_k`), it is
//!
//! ```text
//! min  Σ_{i=1}^{ℓ−1} (C_t Ĉ x_i − r_i)ᵀ Q_i (C_t Ĉ x_i − r_i) + Σ_{i=0}^{ℓ−1} Δu_iᵀ R_i Δu_i   (2.48)
//! s.t. x_{i+1} = Â x_i + B̂ u_i,   Δu_i = u_i − u_{i−1}                   (2.36), (2.43), (2.47)
//! ```
//!
//! with `Q_i`, `R_i` the diagonal blocks of `Q` and `R` ([`super::condense::Weight`]) and
//! `𝓡 = [r_0; …; r_{ℓ−1}]`. The tracking term of `i = 0` is left out: `y_{1|k} = Ĉ x_0`
//! does not depend on `U` (block row 1 of `T̂` (2.46) is zero); and `x_ℓ` enters no term
//! (`u_{ℓ|k}` affects no predicted output: block column `ℓ` of `T̂` is zero). The start
//! state `x_0` is the condenser's: `x_{1|k} = Â x̂_k + B̂ u_k` (2.36) in the dissertation's
//! next-step timing, `x̂_k` with the move reference `u_{k−1}` in the same-step timing, or
//! `x_{N|k}` with the last committed input when PCAC re-plans every `N` samples
//! ([`crate::pcac`]): whatever start state and move reference the condenser's problem
//! was built from. The cost is (2.48) itself, without the condenser's factor 2
//! (`J = ½ Uᵀ H U + fᵀ U + c` with `H = 2(…)`, `f = 2(…)`): a positive factor does not
//! move the minimizer.
//!
//! ## The method: a backward Riccati recursion on the state and the last input
//!
//! The move cost couples `u_i` and `u_{i−1}`, so the recursion runs on the augmented
//! state `z_i = [x_i; u_{i−1}] ∈ ℝ^N`, `N = n̂p + m`, with the move `Δu_i` as its input
//! (standard LQ notation, e.g. Anderson and Moore's; not the dissertation's):
//!
//! ```text
//! z_{i+1} = Ā z_i + B̄ Δu_i,   Ā = [Â  B̂; 0  I_m],   B̄ = [B̂; I_m],   z_0 = [x_0; u_k]
//! stage cost  (E z_i − r_i)ᵀ Q_i (E z_i − r_i) + Δu_iᵀ R_i Δu_i,   E = [C_t Ĉ  0] = [C_t 0 ⋯ 0]
//! ```
//!
//! (no tracking term at `i = 0`). The cost-to-go from step `i` is
//! `V_i(z) = zᵀ P_i z + 2 s_iᵀ z + const`, with `V_ℓ = 0` (`P_ℓ = 0`, `s_ℓ = 0`), and for
//! `i = ℓ−1, …, 0`, minimizing `Δuᵀ R_i Δu + V_{i+1}(Ā z + B̄ Δu)` over `Δu`:
//!
//! ```text
//! S_i = Āᵀ P_{i+1} Ā,   σ_i = Āᵀ s_{i+1}
//! M_i = R_i + B̄ᵀ P_{i+1} B̄,   L_i = B̄ᵀ P_{i+1} Ā,   g_i = B̄ᵀ s_{i+1}
//! K_i = M_i⁻¹ L_i,   k_i = M_i⁻¹ g_i,   Δu_i = −K_i z_i − k_i
//! P_i = S_i − L_iᵀ M_i⁻¹ L_i + Eᵀ Q_i E,   s_i = σ_i − L_iᵀ M_i⁻¹ g_i − Eᵀ Q_i r_i   (i ≥ 1)
//! ```
//!
//! Because `B̄` is the last `m` columns of `Ā`, `L_i` is the last `m` rows of `S_i`,
//! `B̄ᵀ P_{i+1} B̄` its last `m × m` block and `g_i` the last `m` entries of `σ_i`: one
//! product `Āᵀ P Ā` gives all three. `M_i = Λ Λᵀ` (Cholesky, `m × m`), `Z = Λ⁻¹ L_i`, and
//! `L_iᵀ M_i⁻¹ L_i = Zᵀ Z`. `P_0`, `s_0` are not needed. The forward pass then runs
//! `Δu_i = −K_i z_i − k_i`, `u_i = u_{i−1} + Δu_i`, `z_{i+1} = Ā z_i + B̄ Δu_i` from
//! `z_0 = [x_0; u_k]`, and records `y_i = Ĉ x_i` (the first `p` entries of `x_i`), the
//! predicted outputs `Γ̂ x_0 + T̂ U` (2.43) of the plan, which the constraint check
//! ([`super::constraint_check`]) reads.
//!
//! ## When it is exact
//!
//! Always, for the unconstrained minimizer: with `R_i ≻ 0` and `Q_i ⪰ 0` every `P_i` is
//! positive semidefinite and every `M_i ≻ 0`, and dynamic programming on this
//! equality-constrained quadratic program returns its unique minimizer, which is
//! `U* = −H⁻¹ f` of the condensed problem (the same function of `U`). It is the solution
//! of the constrained QP (2.48)–(2.51) exactly when `U*` satisfies every constraint
//! (the problem is strictly convex); [`super::fast_path`] checks that. In floating
//! point it differs from the dense `−H⁻¹ f` by the two methods' rounding: the recursion
//! never forms `H`, whose condition number grows with `ℓ` and the weights' ratio, so
//! where `H` is ill-conditioned it is the more accurate of the two.
//!
//! ## Structure used and cost
//!
//! `Ā` is assembled from `F̂_b`, `Ĝ_b` directly (no dense power of `Â`), and its block
//! companion structure (2.40) is used in every product: the rows of `Āᵀ X` are
//! `−Σ_b F̂_bᵀ X_b` (block 1), `X_{b−1}` (block `b ≥ 2`, a copy) and `B̂ᵀ X_x + X_u` (the
//! last `m` rows), `n̂p (p + m)` row operations instead of `N²`; `E` reads `C_t` on the
//! first `p` states only. `S_i` is computed as `V = Āᵀ P`, `T = Vᵀ = P Ā` (`P` is
//! symmetric), `S_i = Āᵀ T`, and `P_i` as `S_i − Zᵀ Z` row by row. Every `N`-column
//! matrix is stored by rows of a width `w` fixed at compile time (`N` rounded up to a
//! multiple of 4, at most [`Riccati::MAX_N`] `= 32`; the padding columns stay zero), so
//! that a row operation is one unrolled loop of vector instructions with its row
//! accumulated in registers: at the arm's `N = 7` the short, runtime-length loops of a
//! plain implementation cost about twice as much. `S_i`'s products read the rows of `Āᵀ`
//! (no division by a run-time row length in the loops). On a CPU with AVX2 both passes run
//! in a compilation for it, checked once by [`Riccati::new`]: the same multiplications and
//! additions in the same order on four-wide vectors, without fused multiply–adds, so the
//! result is bit for bit the baseline's (the test
//! `the_avx2_form_equals_the_baseline_bit_for_bit`; the ignored test `riccati_timing`
//! times both forms). Per backward step:
//! `2 n̂p (p + m) w` for `Āᵀ P Ā`, `N²` for the transpose, `m N w` for `Zᵀ Z`, `2 m² w` for
//! the Cholesky solves; per forward step `m w + n̂p (p + m)`
//! ([`Riccati::operation_count`]). For the sampling arm (`n̂ = 1`, `p = 5`, `m = 2`,
//! `ℓ = 50`, `w = 8`) that is about 42 k multiply–adds, against about 227 k for condensing
//! and factorizing the dense `100 × 100` `H` (the ignored test `riccati_timing` times both:
//! `cargo test --release -p control --lib riccati_timing -- --ignored --nocapture`); the
//! truss (`n̂ = 25`, `p = 4`: `N = 102`) is beyond the recursion's rows and would cost
//! about 6.3 M against about 105 k ([`super::fast_path`] chooses).
//!
//! ## Real-time use
//!
//! [`Riccati::new`] checks the dimensions and weights and allocates every buffer
//! (`O(ℓ m N + N² + ℓ p²)`); [`Riccati::solve`] allocates nothing, never panics (slices of
//! the wrong length, non-finite data and a non-positive pivot of `M_i` are refused with a
//! [`RiccatiError`]), and runs a fixed number of loops of fixed lengths.

use super::condense::{MpcSpec, SpecError, expand_weight};
use crate::bocf::Realization;

#[cfg(test)]
pub(crate) mod tests;

/// Why [`Riccati::solve`] did not produce a minimizer (no allocation: static descriptions).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RiccatiError {
    /// A slice or the realization has the wrong size.
    Length {
        /// Which argument.
        what: &'static str,
        /// The length expected.
        expected: usize,
        /// The length given.
        got: usize,
    },
    /// An argument holds a NaN or an infinity, or the result does.
    NonFinite {
        /// Which argument (or `"result"`).
        what: &'static str,
    },
    /// `M_i = R_i + B̄ᵀ P_{i+1} B̄` lost its positive definiteness to rounding.
    NotPositiveDefinite,
}

impl core::fmt::Display for RiccatiError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RiccatiError::Length {
                what,
                expected,
                got,
            } => write!(f, "{what}: expected length {expected}, got {got}"),
            RiccatiError::NonFinite { what } => write!(f, "{what}: not finite"),
            RiccatiError::NotPositiveDefinite => {
                write!(f, "R + B̄ᵀ P B̄ is not numerically positive definite")
            }
        }
    }
}

impl std::error::Error for RiccatiError {}

/// The unconstrained minimizer of (2.48) for the realization (2.36)–(2.42) by the Riccati
/// recursion of the module docs, allocation-free after [`Riccati::new`].
#[derive(Clone, Debug)]
pub struct Riccati {
    ell: usize,
    n_hat: usize,
    p: usize,
    m: usize,
    pt: usize,
    /// `n̂p`.
    nx: usize,
    /// `N = n̂p + m`.
    nn: usize,
    /// `R_i`, step-major (`ℓ·m`).
    r: Vec<f64>,
    /// `C_tᵀ Q_i C_t` (`p × p`) per step (`ℓ` blocks; block 0 unused).
    eqe: Vec<f64>,
    /// `C_tᵀ Q_i` (`p × p_t`) per step (`ℓ` blocks; block 0 unused).
    eq: Vec<f64>,
    /// The row stride of the `N`-column matrices: `N` rounded up to a multiple of 4, the
    /// padding columns zero (module docs, "Structure used and cost").
    w: usize,
    /// `Āᵀ` (`N` rows of stride `w`) of the last solve, for the forward pass.
    at: Vec<f64>,
    /// `P_{i+1}`, then `P_i` (`N` rows of stride `w`).
    pm: Vec<f64>,
    /// `V = Āᵀ P_{i+1}`, then `T = Vᵀ = P_{i+1} Ā` (`N` rows of stride `w` each).
    v: Vec<f64>,
    t: Vec<f64>,
    /// `S_i = Āᵀ P_{i+1} Ā` (`N` rows of stride `w`).
    sm: Vec<f64>,
    /// The Cholesky factor `Λ` of `M_i` (`m × m`, lower, row-major).
    chol: Vec<f64>,
    /// `Z = Λ⁻¹ L_i` (`m` rows of stride `w`) and `Λ⁻¹ g_i` (`m`).
    z: Vec<f64>,
    zg: Vec<f64>,
    /// `K_i` (`ℓ` blocks of `m` rows of stride `w`) and `k_i` (`ℓ` blocks of `m`).
    gain: Vec<f64>,
    offset: Vec<f64>,
    /// `U*` (`ℓ·m`) and its predicted outputs `y_0 … y_{ℓ−1}` (`ℓ·p`).
    u: Vec<f64>,
    y: Vec<f64>,
    /// Whether the passes run in their AVX2 compilation (module docs, "Structure used and
    /// cost"), found by [`Riccati::new`].
    avx2: bool,
}

impl Riccati {
    /// The largest `N = n̂p + m` the recursion takes: its rows are arrays of a width fixed
    /// at compile time (module docs, "Structure used and cost"), up to 32.
    pub const MAX_N: usize = 32;

    /// Checks the spec's dimensions, `C_t` and weights (as [`super::condense::Condenser::new`]
    /// does; the bounds and output constraints are not used here) for a model of order
    /// `n_hat`, and allocates every buffer.
    pub fn new(spec: &MpcSpec, n_hat: usize) -> Result<Self, SpecError> {
        let (ell, m, p, pt) = (spec.horizon, spec.n_inputs, spec.n_outputs, spec.n_tracked);
        if ell == 0 || m == 0 || p == 0 || pt == 0 || n_hat == 0 {
            return Err(SpecError(format!(
                "horizon, n_inputs, n_outputs, n_tracked and n_hat must be at least 1, got \
                 {ell}, {m}, {p}, {pt}, {n_hat}"
            )));
        }
        if spec.tracking.len() != pt * p || spec.tracking.iter().any(|x| !x.is_finite()) {
            return Err(SpecError(format!(
                "tracking (C_t): expected {} finite values, got {}",
                pt * p,
                spec.tracking.len()
            )));
        }
        let (q, _) = expand_weight(&spec.q, "q (tracking weight Q)", pt, ell, false)?;
        let (r, _) = expand_weight(&spec.r, "r (move weight R)", m, ell, true)?;
        let ct = &spec.tracking;
        let mut eqe = vec![0.0; ell * p * p];
        let mut eq = vec![0.0; ell * p * pt];
        for i in 0..ell {
            let qi = &q[i * pt..(i + 1) * pt];
            for a in 0..p {
                for t in 0..pt {
                    eq[(i * p + a) * pt + t] = ct[t * p + a] * qi[t];
                }
                for b in 0..p {
                    eqe[(i * p + a) * p + b] =
                        (0..pt).map(|t| ct[t * p + a] * qi[t] * ct[t * p + b]).sum();
                }
            }
        }
        let nx = n_hat * p;
        let nn = nx + m;
        if nn > Self::MAX_N {
            return Err(SpecError(format!(
                "the Riccati recursion takes n̂p + m ≤ {}, got {n_hat}·{p} + {m} = {nn}",
                Self::MAX_N
            )));
        }
        let w = nn.div_ceil(4) * 4;
        Ok(Self {
            ell,
            n_hat,
            p,
            m,
            pt,
            nx,
            nn,
            r,
            eqe,
            eq,
            w,
            at: vec![0.0; nn * w],
            pm: vec![0.0; nn * w],
            v: vec![0.0; nn * w],
            t: vec![0.0; nn * w],
            sm: vec![0.0; nn * w],
            chol: vec![0.0; m * m],
            z: vec![0.0; m * w],
            zg: vec![0.0; m],
            gain: vec![0.0; ell * m * w],
            offset: vec![0.0; ell * m],
            u: vec![0.0; ell * m],
            y: vec![0.0; ell * p],
            avx2: avx2_available(),
        })
    }

    /// Multiply–adds of one [`Riccati::solve`] for order `n_hat`, `p` outputs, `m` inputs
    /// and horizon `ℓ` (module docs, "Structure used and cost"), with `N = n̂p + m` and the
    /// row width `w` (`N` rounded up to a multiple of 4):
    /// `ℓ (2 n̂p (p + m) w + N² + m N w + 2 m² w) + ℓ (m w + n̂p (p + m))`. Saturates
    /// instead of overflowing.
    pub fn operation_count(n_hat: usize, p: usize, m: usize, ell: usize) -> u64 {
        let [n_hat, p, m, ell] = [n_hat, p, m, ell].map(|v| v as u64);
        let nx = n_hat.saturating_mul(p);
        let nn = nx.saturating_add(m);
        let w = nn.div_ceil(4).saturating_mul(4);
        let a_rows = nx.saturating_mul(p.saturating_add(m));
        let backward = (2 * a_rows)
            .saturating_mul(w)
            .saturating_add(nn.saturating_mul(nn))
            .saturating_add(m.saturating_mul(nn).saturating_mul(w))
            .saturating_add((2 * m).saturating_mul(m).saturating_mul(w));
        let forward = m.saturating_mul(w).saturating_add(a_rows);
        ell.saturating_mul(backward.saturating_add(forward))
    }

    /// The horizon `ℓ`.
    pub fn horizon(&self) -> usize {
        self.ell
    }

    /// `U* = [u_{1|k}; …; u_{ℓ|k}]` of the last successful [`Riccati::solve`] (`ℓ·m`).
    pub fn u(&self) -> &[f64] {
        &self.u
    }

    /// The predicted outputs `y_{1|k} … y_{ℓ|k}` (2.43) of `U*` (`ℓ·p`).
    pub fn outputs(&self) -> &[f64] {
        &self.y
    }

    /// Computes `U*` and its predicted outputs (module docs) for the realization `real`
    /// (order `n̂`, `p`, `m` of [`Riccati::new`]), the start state `x0` (`n̂p`: `x_{1|k}`, or
    /// `x̂_k` in the same-step timing), the move reference `u_k` (`m`) and the command
    /// `𝓡 = reference` (`ℓ·p_t`, step-major). Allocation-free; every value must be finite.
    ///
    /// # Errors
    ///
    /// [`RiccatiError`]: wrong sizes, non-finite data or result, or a non-positive pivot.
    /// `U*` is then not meaningful.
    pub fn solve(
        &mut self,
        real: &Realization<'_>,
        x0: &[f64],
        u_k: &[f64],
        reference: &[f64],
    ) -> Result<(), RiccatiError> {
        let (ell, p, m, nx) = (self.ell, self.p, self.m, self.nx);
        let dims = [
            ("realization n_hat", real.n_hat(), self.n_hat),
            ("realization p", real.p(), p),
            ("realization m", real.m(), m),
            ("x0", x0.len(), nx),
            ("u_k", u_k.len(), m),
            ("reference", reference.len(), ell * self.pt),
        ];
        for (what, got, expected) in dims {
            if got != expected {
                return Err(RiccatiError::Length {
                    what,
                    expected,
                    got,
                });
            }
        }
        let finite = |v: &[f64]| v.iter().fold(true, |ok, x| ok & x.is_finite());
        for (what, v) in [
            ("coefficients", real.coefficients()),
            ("x0", x0),
            ("u_k", u_k),
            ("reference", reference),
        ] {
            if !finite(v) {
                return Err(RiccatiError::NonFinite { what });
            }
        }
        self.load(real);
        match self.w {
            4 => self.run::<4>(x0, u_k, reference)?,
            8 => self.run::<8>(x0, u_k, reference)?,
            12 => self.run::<12>(x0, u_k, reference)?,
            16 => self.run::<16>(x0, u_k, reference)?,
            20 => self.run::<20>(x0, u_k, reference)?,
            24 => self.run::<24>(x0, u_k, reference)?,
            28 => self.run::<28>(x0, u_k, reference)?,
            32 => self.run::<32>(x0, u_k, reference)?,
            w => {
                // Refused by `new`.
                return Err(RiccatiError::Length {
                    what: "n̂p + m rounded up to a multiple of 4",
                    expected: Self::MAX_N,
                    got: w,
                });
            }
        }
        if !(finite(&self.u) && finite(&self.y)) {
            return Err(RiccatiError::NonFinite { what: "result" });
        }
        Ok(())
    }

    /// `Āᵀ` by rows (stride `w`) from `F̂_b`, `Ĝ_b` of `real` (module docs): row `t < p`
    /// holds `−F̂`'s column `t` (stacked over the blocks), row `p ≤ k < n̂p` the shift
    /// `e_{k−p}`, row `n̂p + j` `B̂`'s column `j` and the `1` of `I_m`; the padding zero.
    fn load(&mut self, real: &Realization<'_>) {
        let (n_hat, p, m, nx, w) = (self.n_hat, self.p, self.m, self.nx, self.w);
        let at = &mut self.at;
        at.fill(0.0);
        for b in 0..n_hat {
            for r in 0..p {
                let k = b * p + r;
                for t in 0..p {
                    at[t * w + k] = -real.f(b + 1, r, t);
                }
                if k + p < nx {
                    at[(k + p) * w + k] = 1.0;
                }
                for j in 0..m {
                    at[(nx + j) * w + k] = real.g(b + 1, r, j);
                }
            }
        }
        for j in 0..m {
            at[(nx + j) * w + nx + j] = 1.0;
        }
    }

    /// Both passes with rows of the compile-time width `W` (= `self.w`).
    fn run<const W: usize>(
        &mut self,
        x0: &[f64],
        u_k: &[f64],
        reference: &[f64],
    ) -> Result<(), RiccatiError> {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is true only when the CPU has AVX2 (`avx2_available`).
            return unsafe { self.run_avx2::<W>(x0, u_k, reference) };
        }
        self.run_body::<W>(x0, u_k, reference)
    }

    /// [`Riccati::run_body`] compiled with AVX2: the same operations in the same order on
    /// wider vectors (no fused multiply–add), so bit for bit the baseline's result.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn run_avx2<const W: usize>(
        &mut self,
        x0: &[f64],
        u_k: &[f64],
        reference: &[f64],
    ) -> Result<(), RiccatiError> {
        self.run_body::<W>(x0, u_k, reference)
    }

    /// Both passes, inlined into [`Riccati::run`] or into its AVX2 compilation.
    #[inline(always)]
    fn run_body<const W: usize>(
        &mut self,
        x0: &[f64],
        u_k: &[f64],
        reference: &[f64],
    ) -> Result<(), RiccatiError> {
        self.backward::<W>(reference)?;
        self.forward::<W>(x0, u_k);
        Ok(())
    }

    /// The backward pass: `K_i`, `k_i` for `i = ℓ−1, …, 0`, on rows of width `W`.
    #[inline(always)]
    fn backward<const W: usize>(&mut self, reference: &[f64]) -> Result<(), RiccatiError> {
        let Self {
            ell,
            p,
            m,
            pt,
            nx,
            nn,
            r,
            eqe,
            eq,
            pm,
            v,
            t,
            at,
            sm,
            chol,
            z,
            zg,
            gain,
            offset,
            ..
        } = self;
        let (ell, p, m, pt, nx, nn) = (*ell, *p, *m, *pt, *nx, *nn);
        let shape = Shape { p, nx };
        let pm = pm.as_chunks_mut::<W>().0;
        let v = v.as_chunks_mut::<W>().0;
        let t = t.as_chunks_mut::<W>().0;
        let sm = sm.as_chunks_mut::<W>().0;
        let at = at.as_chunks::<W>().0;
        let z = z.as_chunks_mut::<W>().0;
        let gain = gain.as_chunks_mut::<W>().0;
        // P_ℓ = 0, s_ℓ = 0; the padding columns of every row stay zero.
        pm.fill([0.0; W]);
        t.fill([0.0; W]);
        let mut s = [0.0; W];
        let mut sigma = [0.0; W];
        for i in (0..ell).rev() {
            // S = Āᵀ P Ā as V = Āᵀ P, T = Vᵀ = P Ā, S = Āᵀ T.
            shape.transpose_a_times(at, pm, v);
            for (row, vrow) in v.iter().enumerate() {
                for (trow, x) in t.iter_mut().zip(&vrow[..nn]) {
                    trow[row] = *x;
                }
            }
            shape.transpose_a_times(at, t, sm);
            // σ = Āᵀ s.
            for (g, arow) in sigma.iter_mut().zip(at) {
                *g = dot_row(arow, &s);
            }
            let gu = &sigma[nx..nn];
            // M = R_i + S_uu = Λ Λᵀ (S_uu: the last m rows and columns of S).
            let su = &sm[nx..nn];
            for a in 0..m {
                for c in 0..=a {
                    let mut val = su[a][nx + c];
                    if a == c {
                        val += r[i * m + a];
                    }
                    for k in 0..c {
                        val -= chol[a * m + k] * chol[c * m + k];
                    }
                    if a == c {
                        if !(val > 0.0 && val.is_finite()) {
                            return Err(RiccatiError::NotPositiveDefinite);
                        }
                        chol[a * m + a] = val.sqrt();
                    } else {
                        chol[a * m + c] = val / chol[c * m + c];
                    }
                }
            }
            // Z = Λ⁻¹ L (L = the last m rows of S), Λ⁻¹ g (g = σ_u).
            for a in 0..m {
                let (done, rest) = z.split_at_mut(a);
                let za = &mut rest[0];
                *za = su[a];
                let mut zga = gu[a];
                for (c, zc) in done.iter().enumerate() {
                    let l = chol[a * m + c];
                    axpy_row(-l, zc, za);
                    zga -= l * zg[c];
                }
                let d = 1.0 / chol[a * m + a];
                za.iter_mut().for_each(|x| *x *= d);
                zg[a] = zga * d;
            }
            // K_i = Λ⁻ᵀ Z, k_i = Λ⁻ᵀ Λ⁻¹ g.
            let gain_i = &mut gain[i * m..(i + 1) * m];
            let off = &mut offset[i * m..(i + 1) * m];
            for a in (0..m).rev() {
                let (head, tail) = gain_i.split_at_mut(a + 1);
                let ka = &mut head[a];
                *ka = z[a];
                let mut ko = zg[a];
                for (c, kc) in tail.iter().enumerate() {
                    let l = chol[(a + 1 + c) * m + a];
                    axpy_row(-l, kc, ka);
                    ko -= l * off[a + 1 + c];
                }
                let d = 1.0 / chol[a * m + a];
                ka.iter_mut().for_each(|x| *x *= d);
                off[a] = ko * d;
            }
            if i == 0 {
                break;
            }
            // P_i = S − ZᵀZ + EᵀQ_iE,   s_i = σ − Zᵀ(Λ⁻¹g) − EᵀQ_i r_i.
            for (k, (prow, srow)) in pm.iter_mut().zip(sm.iter()).enumerate() {
                let mut acc = *srow;
                for za in z.iter() {
                    axpy_row(-za[k], za, &mut acc);
                }
                *prow = acc;
            }
            s = sigma;
            for (za, zga) in z.iter().zip(zg.iter()) {
                axpy_row(-zga, za, &mut s);
            }
            let eqe_i = &eqe[i * p * p..(i + 1) * p * p];
            // Rows by index: `chunks_exact` with a run-time length divides at every call.
            for (a, row) in pm[..p].iter_mut().enumerate() {
                let erow = &eqe_i[a * p..(a + 1) * p];
                row[..p].iter_mut().zip(erow).for_each(|(x, e)| *x += e);
            }
            let eq_i = &eq[i * p * pt..(i + 1) * p * pt];
            let ri = &reference[i * pt..(i + 1) * pt];
            for (a, sv) in s[..p].iter_mut().enumerate() {
                let erow = &eq_i[a * pt..(a + 1) * pt];
                *sv -= erow.iter().zip(ri).map(|(e, r)| e * r).sum::<f64>();
            }
        }
        Ok(())
    }

    /// The forward pass from `z_0 = [x0; u_k]`: `U*` and the outputs `y_i = Ĉ x_i`, with
    /// `z_{i+1} = Ā z_i + B̄ Δu_i = Ā [x_i; u_i]` (`B̄` is the last `m` columns of `Ā`),
    /// accumulated over the rows of `Āᵀ`.
    #[inline(always)]
    fn forward<const W: usize>(&mut self, x0: &[f64], u_k: &[f64]) {
        let (ell, p, m, nx, nn) = (self.ell, self.p, self.m, self.nx, self.nn);
        let at = self.at.as_chunks::<W>().0;
        let gain = self.gain.as_chunks::<W>().0;
        let mut zf = [0.0; W];
        zf[..nx].copy_from_slice(x0);
        zf[nx..nn].copy_from_slice(u_k);
        for i in 0..ell {
            self.y[i * p..(i + 1) * p].copy_from_slice(&zf[..p]);
            let off = &self.offset[i * m..(i + 1) * m];
            let ui = &mut self.u[i * m..(i + 1) * m];
            for (j, (u, krow)) in ui.iter_mut().zip(&gain[i * m..(i + 1) * m]).enumerate() {
                *u = zf[nx + j] - dot_row(krow, &zf) - off[j];
            }
            if i + 1 == ell {
                break;
            }
            zf[nx..nn].copy_from_slice(ui);
            let mut next = [0.0; W];
            for (zk, row) in zf[..nn].iter().zip(at) {
                axpy_row(*zk, row, &mut next);
            }
            zf = next;
        }
    }
}

/// Whether this CPU runs AVX2 (always false off x86-64).
fn avx2_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The dimensions [`Shape::transpose_a_times`] needs.
#[derive(Clone, Copy)]
struct Shape {
    p: usize,
    nx: usize,
}

impl Shape {
    /// `out = Āᵀ x` for the `N` rows `x` into the `N` rows `out`, by rows,
    /// `out_a = Σ_k Ā_{k,a} x_k`, over the nonzeros of `Ā` (module docs): row block 1 of
    /// `Āᵀ` is `[−F̂_1ᵀ … −F̂_n̂ᵀ 0]`, row block `b ≥ 2` picks `x`'s block `b − 1`, and the
    /// last `m` rows are `[B̂ᵀ I_m]`; those rows are read from `at` (`Āᵀ` by rows).
    #[inline(always)]
    fn transpose_a_times<const W: usize>(
        self,
        at: &[[f64; W]],
        x: &[[f64; W]],
        out: &mut [[f64; W]],
    ) {
        let Self { p, nx } = self;
        let (ox, ou) = out.split_at_mut(nx);
        let (xx, xu) = x.split_at(nx);
        let (at_x, at_u) = at.split_at(nx);
        // Each output row is accumulated in registers, then stored once.
        for (dst, arow) in ox[..p].iter_mut().zip(at_x) {
            let mut acc = [0.0; W];
            for (src, a) in xx.iter().zip(&arow[..nx]) {
                axpy_row(*a, src, &mut acc);
            }
            *dst = acc;
        }
        ox[p..].copy_from_slice(&xx[..nx - p]);
        for ((dst, own), arow) in ou.iter_mut().zip(xu).zip(at_u) {
            let mut acc = *own;
            for (src, a) in xx.iter().zip(&arow[..nx]) {
                axpy_row(*a, src, &mut acc);
            }
            *dst = acc;
        }
    }
}

/// `y ← y + a x` on rows of the compile-time width `W` (unrolled and vectorized).
#[inline(always)]
fn axpy_row<const W: usize>(a: f64, x: &[f64; W], y: &mut [f64; W]) {
    for (yl, xl) in y.iter_mut().zip(x) {
        *yl += a * xl;
    }
}

/// `Σ_l a_l b_l` on rows of the compile-time width `W` (a multiple of 4), with four
/// partial sums.
#[inline(always)]
fn dot_row<const W: usize>(a: &[f64; W], b: &[f64; W]) -> f64 {
    let mut acc = [0.0; 4];
    for (a4, b4) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for l in 0..4 {
            acc[l] += a4[l] * b4[l];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3])
}
