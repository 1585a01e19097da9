//! The block observable canonical realization of an identified input–output model, its
//! Markov parameters and its free response: dissertation (2.36)–(2.46).
//!
//! # The model it realizes
//!
//! `p` outputs, `m` inputs, order `n̂ ≥ 1`: the input–output model (2.24)
//!
//! ```text
//! ŷ_k = − Σ_{i=1}^{n̂} F̂_i y_{k−i} + Σ_{i=1}^{n̂} Ĝ_i u_{k−i}                        (2.24)
//! ```
//!
//! with the coefficients given as `Θ̃ = [F̂_1 … F̂_n̂ Ĝ_1 … Ĝ_n̂] ∈ ℝ^{p×N}`, `N = n̂(p+m)`,
//! row-major (`θ = vec Θ̃` of (2.27)): `F̂_i` occupies columns `(i−1)p .. ip`, `Ĝ_i`
//! columns `n̂p + (i−1)m .. n̂p + im`. [`Realization`] is a borrowed view of such a `Θ̃`;
//! PCAC's identification ([`crate::pcac::IoModel`], (2.24)–(2.35)) produces it at every
//! step as `θ_{k+1}`, written `F̂_{i,k+1}`, `Ĝ_{i,k+1}` below.
//!
//! # The realization (2.36)–(2.42)
//!
//! ```text
//! x_{1|k} = Â_k x̂_k + B̂_k u_k,   y_k = Ĉ x̂_k                                  (2.36)–(2.37)
//! x̂_{1,k} = y_k                                                                 (2.38)
//! x̂_{i,k} = Σ_{j=1}^{n̂−i+1} (−F̂_{i+j−1,k+1} y_{k−j} + Ĝ_{i+j−1,k+1} u_{k−j}),  i ≥ 2  (2.39)
//! Â_k: −F̂_{i,k+1} in block (i, 1), I_p in blocks (i, i+1), zeros elsewhere       (2.40)
//! B̂_k = [Ĝ_{1,k+1}; …; Ĝ_{n̂,k+1}],   Ĉ = [I_p 0 … 0]                        (2.41)–(2.42)
//! ```
//!
//! The state estimate `x̂_k` uses the data window
//!
//! ```text
//! x̂_k:  y_k, y_{k−1}, …, y_{k−n̂+1}   and   u_{k−1}, …, u_{k−n̂+1}
//! ```
//!
//! which a model provides through [`DataWindow`] (`y_{k−n̂}` and `u_{k−n̂}` enter `θ_{k+1}`
//! but not `x̂_k`). Then `Ĉ x_{1|k} = Ĉ (Â_k x̂_k + B̂_k u_k) = −F̂_1 y_k + x̂_{2,k} + Ĝ_1 u_k`
//! is exactly the one-step prediction of (2.24) for `y_{k+1}` with the coefficients
//! `θ_{k+1}`: the block rows of `Â_k x̂_k + B̂_k u_k` are
//! `x_{i|k} = −F̂_i y_k + x̂_{i+1,k} + Ĝ_i u_k`, the state recursion of the companion form,
//! by which `x̂_{i,k}` (2.39) is the part of the future output `y_{k+i−1}` that past data
//! already determine.
//!
//! # Markov parameters and free response (2.43)–(2.46)
//!
//! The `ℓ`-step prediction (2.43) is `Y_{1|k,ℓ} = Γ̂_{k,ℓ} x_{1|k} + T̂_{k,ℓ} U_{1|k,ℓ}`,
//! `Y_{1|k,ℓ} = [y_{1|k}; …; y_{ℓ|k}]`, `U_{1|k,ℓ} = [u_{1|k}; …; u_{ℓ|k}]` (2.44),
//! with the observability matrix `Γ̂_{k,ℓ} = [Ĉ; Ĉ Â_k; …; Ĉ Â_k^{ℓ−1}]` (2.45) and the
//! block Toeplitz `T̂_{k,ℓ}` (2.46) of the Markov parameters `Ĥ_{k,i} = Ĉ Â_k^{i−1} B̂_k`
//! (defined with (2.46)). Both are computed from the companion structure without forming
//! powers of `Â_k`:
//!
//! ```text
//! Ĥ_i = Ĝ_i − Σ_{j=1}^{min(i−1, n̂)} F̂_j Ĥ_{i−j}       (Ĝ_i = 0 for i > n̂)
//! ```
//!
//! the coefficient of `z^{−i}` in `(I + Σ F̂_j z^{−j}) H(z) = Σ Ĝ_j z^{−j}`: `O(ℓ n̂ p² m)`
//! for `ℓ` of them, no `n̂p × n̂p` matrix involved ([`Realization::markov`]). The free
//! response `y_i = Ĉ Â^{i−1} x_1`, `i = 1 … ℓ` (`Γ̂_{k,ℓ} x_{1|k}`), obeys the same
//! recursion with the blocks of `x_1 = [x_1^{(1)}; …; x_1^{(n̂)}]` in place of the `Ĝ_i`:
//!
//! ```text
//! y_i = x_1^{(i)} − Σ_{j=1}^{min(i−1, n̂)} F̂_j y_{i−j}       (x_1^{(i)} = 0 for i > n̂)
//! ```
//!
//! because `x ← Â x` sets block `b` to `−F̂_b x^{(1)} + x^{(b+1)}` (2.40), so that block 1
//! after `i − 1` steps is `x_1^{(i)}` less `F̂_j y_{i−j}` for each `j`: `O(ℓ n̂ p²)`, and no
//! state to propagate ([`Realization::free_response`]). [`HorizonPrediction`] holds the
//! buffers of all of them for one horizon and computes them together for the condensing
//! in [`crate::mpc`].
//!
//! # Cost
//!
//! All three are short sums of products with the rows of `Θ̃`. For the truss (`n̂ = 25`,
//! `p = 4`, `m = 2`, `ℓ = 40`) the Markov parameters take 21 600 multiply–adds
//! (`Σ_{i≤ℓ} min(i−1, n̂) = 675` products `F̂_j Ĥ_{i−j}`), the free response 10 800 (the same
//! 675 products with `p × 1` blocks; propagating the state took `(ℓ−1) n̂ p² = 15 600`) and
//! the state estimate (2.39) 7 200 (`n̂(n̂−1)/2 = 300` products of a block pair with the
//! data). What made them slow was how the arithmetic was reached, not its amount, so the
//! kernels
//!
//! - sum in **tiles** of at most 4 rows × 2 columns of the result (`Ĥ_i`, `y_i` or `x̂_i`):
//!   the up to 8 sums of a tile are independent and stay in registers through the whole
//!   sum, where adding each term to the result in memory made every term wait for the
//!   store of the last one. The tile shapes are compile-time constants; the 8 of them
//!   (1–4 rows × 1–2 columns) cover every `p` and `m`;
//! - walk each row of `Θ̃` (`[F̂_1 … F̂_n̂ Ĝ_1 … Ĝ_n̂]`, contiguous) through slices taken once
//!   per block, with index arithmetic rather than `chunks_exact` over the run-time `p` or
//!   `m` (whose set-up divides), and without a test for zero coefficients (a branch per
//!   coefficient that identified models never take);
//! - read the data window once per lag `j` in [`Realization::fill_state`]: `2(n̂−1)` reads
//!   instead of `n̂(n̂−1)p`, each an index into a ring buffer with a division.
//!
//! Every entry is still summed over the same terms in the same order as the formulas
//! above are written — the Markov parameters and the state over `j` ascending, the free
//! response over `j` descending, which is the order in which propagating `x ← Â x` adds
//! them — so the results are bit for bit those of the plain loops; the tests check this
//! for shapes that use every tile.
//!
//! # Real time
//!
//! [`Realization`] borrows the coefficients and owns nothing; [`HorizonPrediction`] is
//! sized in [`HorizonPrediction::new`]. Every routine after construction never allocates
//! and never panics: slices of the wrong length are refused with a [`DimError`] (a `Copy`
//! value, no allocation).

#![allow(clippy::needless_range_loop)] // index-heavy block algebra

use std::fmt;

/// A slice of the wrong length handed to a model or realization routine; nothing was
/// changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DimError {
    /// Which argument.
    pub what: &'static str,
    /// The length it must have.
    pub expected: usize,
    /// The length it had.
    pub got: usize,
}

impl fmt::Display for DimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} has length {}, expected {}",
            self.what, self.got, self.expected
        )
    }
}

impl std::error::Error for DimError {}

/// `Ok` when `got == expected`, else the [`DimError`] naming `what`.
pub(crate) fn check(what: &'static str, got: usize, expected: usize) -> Result<(), DimError> {
    if got == expected {
        Ok(())
    } else {
        Err(DimError {
            what,
            expected,
            got,
        })
    }
}

/// The number of blocks of `blk` values in a slice of length `got`, or the [`DimError`]
/// naming `what` (expecting the largest whole number of blocks) when `got` is not a
/// multiple of `blk`.
fn blocks(what: &'static str, got: usize, blk: usize) -> Result<usize, DimError> {
    if got.is_multiple_of(blk) {
        Ok(got / blk)
    } else {
        Err(DimError {
            what,
            expected: (got / blk) * blk,
            got,
        })
    }
}

/// The past data the state estimate `x̂_k` (2.38)–(2.39) is built from, at step `k`.
pub trait DataWindow {
    /// `y_{k−j}` (length `p`), for `0 ≤ j < n̂`; zeros before the first sample.
    fn past_output(&self, j: usize) -> &[f64];
    /// `u_{k−j}` (length `m`), for `1 ≤ j < n̂`; zeros before the first sample.
    fn past_input(&self, j: usize) -> &[f64];
}

/// An identified input–output model (2.24) that can be realized at its current step: its
/// coefficients `θ_{k+1}` and its data window. [`HorizonPrediction`] works on any of them.
pub trait IdentifiedModel: DataWindow {
    /// The realization (2.36)–(2.42) of the current coefficients.
    fn realization(&self) -> Realization<'_>;
}

/// The block observable canonical realization (2.36)–(2.42) of the coefficients
/// `Θ̃ = [F̂_1 … F̂_n̂ Ĝ_1 … Ĝ_n̂]` (borrowed, `p × n̂(p+m)` row-major): `Â`, `B̂`, the state
/// estimate, the state step, the Markov parameters and the free response, all computed
/// from the companion structure (see the module docs).
#[derive(Debug, Clone, Copy)]
pub struct Realization<'a> {
    n_hat: usize,
    p: usize,
    m: usize,
    /// `N = n̂(p+m)`.
    nr: usize,
    /// `Θ̃`, p×N row-major.
    coef: &'a [f64],
}

impl<'a> Realization<'a> {
    /// The realization of the order-`n̂` model with `p` outputs, `m` inputs and the
    /// coefficients `coef` = `Θ̃` (`p × n̂(p+m)`, row-major).
    ///
    /// # Errors
    ///
    /// [`DimError`] when `n̂`, `p` or `m` is zero (`expected` 1, `got` 0) or `coef` does
    /// not have length `n̂p(p+m)`.
    pub fn new(n_hat: usize, p: usize, m: usize, coef: &'a [f64]) -> Result<Self, DimError> {
        check("n_hat (at least 1)", n_hat.min(1), 1)?;
        check("p (at least 1)", p.min(1), 1)?;
        check("m (at least 1)", m.min(1), 1)?;
        check("coefficients", coef.len(), n_hat * (p + m) * p)?;
        Ok(Self::new_unchecked(n_hat, p, m, coef))
    }

    /// [`Realization::new`] for dimensions and a slice the caller has validated
    /// (`n̂, p, m ≥ 1`, `coef.len() = n̂p(p+m)`).
    #[inline]
    pub(crate) fn new_unchecked(n_hat: usize, p: usize, m: usize, coef: &'a [f64]) -> Self {
        debug_assert!(n_hat >= 1 && p >= 1 && m >= 1);
        debug_assert_eq!(coef.len(), n_hat * (p + m) * p);
        Self {
            n_hat,
            p,
            m,
            nr: n_hat * (p + m),
            coef,
        }
    }

    /// Model order `n̂`.
    pub fn n_hat(&self) -> usize {
        self.n_hat
    }

    /// Number of outputs `p`.
    pub fn p(&self) -> usize {
        self.p
    }

    /// Number of inputs `m`.
    pub fn m(&self) -> usize {
        self.m
    }

    /// State dimension `n̂p`.
    pub fn state_dim(&self) -> usize {
        self.n_hat * self.p
    }

    /// `Θ̃` (`p × n̂(p+m)`, row-major).
    pub fn coefficients(&self) -> &'a [f64] {
        self.coef
    }

    /// Entry `(r, s)` of `F̂_i` (`1 ≤ i ≤ n̂`, `r, s < p`).
    #[inline]
    pub fn f(&self, i: usize, r: usize, s: usize) -> f64 {
        self.coef[r * self.nr + (i - 1) * self.p + s]
    }

    /// Entry `(r, s)` of `Ĝ_i` (`1 ≤ i ≤ n̂`, `r < p`, `s < m`).
    #[inline]
    pub fn g(&self, i: usize, r: usize, s: usize) -> f64 {
        self.coef[r * self.nr + self.n_hat * self.p + (i - 1) * self.m + s]
    }

    /// Row `r < p` of `Θ̃`, split into its `F̂` part `[F̂_1 … F̂_n̂]` (row `r` of each,
    /// `n̂p` entries) and its `Ĝ` part `[Ĝ_1 … Ĝ_n̂]` (`n̂m` entries).
    #[inline]
    fn row(&self, r: usize) -> (&'a [f64], &'a [f64]) {
        self.coef[r * self.nr..(r + 1) * self.nr].split_at(self.n_hat * self.p)
    }

    /// Fills `Â` (2.40) into `a` (`n̂p × n̂p`, row-major): `−F̂_i` in block `(i, 1)`,
    /// `I_p` in blocks `(i, i+1)`, zeros elsewhere.
    ///
    /// # Errors
    ///
    /// [`DimError`] for the wrong length.
    pub fn fill_a(&self, a: &mut [f64]) -> Result<(), DimError> {
        let nx = self.state_dim();
        check("A", a.len(), nx * nx)?;
        a.fill(0.0);
        let p = self.p;
        for i in 1..=self.n_hat {
            for r in 0..p {
                let row = (i - 1) * p + r;
                for s in 0..p {
                    a[row * nx + s] = -self.f(i, r, s);
                }
                if i < self.n_hat {
                    a[row * nx + i * p + r] = 1.0;
                }
            }
        }
        Ok(())
    }

    /// Fills `B̂ = [Ĝ_1; …; Ĝ_n̂]` (2.41) into `b` (`n̂p × m`, row-major).
    ///
    /// # Errors
    ///
    /// [`DimError`] for the wrong length.
    pub fn fill_b(&self, b: &mut [f64]) -> Result<(), DimError> {
        let (p, m) = (self.p, self.m);
        check("B", b.len(), self.state_dim() * m)?;
        for i in 1..=self.n_hat {
            for r in 0..p {
                for s in 0..m {
                    b[((i - 1) * p + r) * m + s] = self.g(i, r, s);
                }
            }
        }
        Ok(())
    }

    /// Fills the state estimate `x̂_k` (2.38)–(2.39) into `x` (length `n̂p`):
    /// `x̂_{1,k} = y_k` and `x̂_{i,k} = Σ_{j=1}^{n̂−i+1} (−F̂_{i+j−1} y_{k−j} + Ĝ_{i+j−1} u_{k−j})`
    /// with these coefficients and the data of `data`: `O(n̂² p (p+m))`, each datum fetched
    /// from `data` once (module docs, "Cost").
    ///
    /// # Errors
    ///
    /// [`DimError`] for the wrong length.
    pub fn fill_state<W: DataWindow + ?Sized>(
        &self,
        data: &W,
        x: &mut [f64],
    ) -> Result<(), DimError> {
        let (n_hat, p) = (self.n_hat, self.p);
        check("x_hat", x.len(), n_hat * p)?;
        let (x1, rest) = x.split_at_mut(p);
        x1.copy_from_slice(data.past_output(0));
        rest.fill(0.0);
        // y_{k−j}, u_{k−j} enter x̂_i for i = 2 … n̂−j+1, with F̂_{i+j−1}, Ĝ_{i+j−1}.
        for j in 1..n_hat {
            let (y, u) = (data.past_output(j), data.past_input(j));
            for r0 in (0..p).step_by(TILE_ROWS) {
                match (p - r0).min(TILE_ROWS) {
                    4 => self.state_tile::<4>(j, r0, y, u, rest),
                    3 => self.state_tile::<3>(j, r0, y, u, rest),
                    2 => self.state_tile::<2>(j, r0, y, u, rest),
                    _ => self.state_tile::<1>(j, r0, y, u, rest),
                }
            }
        }
        Ok(())
    }

    /// Adds the terms of `y_{k−j}`, `u_{k−j}` (`y`, `u`) to rows `r0 .. r0+R` of
    /// `x̂_2 … x̂_{n̂−j+1}` (`rest` = `x̂_2 … x̂_n̂`): `x̂_i[r] −= F̂_{i+j−1}[r, :] y_{k−j}`
    /// then `x̂_i[r] += Ĝ_{i+j−1}[r, :] u_{k−j}`, each sum over the columns ascending.
    #[inline(always)]
    fn state_tile<const R: usize>(
        &self,
        j: usize,
        r0: usize,
        y: &[f64],
        u: &[f64],
        rest: &mut [f64],
    ) {
        let (n_hat, p, m) = (self.n_hat, self.p, self.m);
        let rows: [(&[f64], &[f64]); R] = std::array::from_fn(|rr| self.row(r0 + rr));
        let (py, mu) = (p.min(y.len()), m.min(u.len()));
        for b in 1..=n_hat - j {
            // x̂_{b+1} takes F̂_l, Ĝ_l with l = b + j (0-based l − 1 below).
            let l = b + j - 1;
            let xb = &mut rest[(b - 1) * p + r0..][..R];
            let mut acc: [f64; R] = std::array::from_fn(|rr| xb[rr]);
            let f: [&[f64]; R] = std::array::from_fn(|rr| &rows[rr].0[l * p..][..p]);
            for s in 0..py {
                for (a, f) in acc.iter_mut().zip(&f) {
                    *a -= f[s] * y[s];
                }
            }
            let g: [&[f64]; R] = std::array::from_fn(|rr| &rows[rr].1[l * m..][..m]);
            for s in 0..mu {
                for (a, g) in acc.iter_mut().zip(&g) {
                    *a += g[s] * u[s];
                }
            }
            xb.copy_from_slice(&acc);
        }
    }

    /// `x_{1|k} = Â x̂ + B̂ u` (2.36) from the structure, `O(n̂ p (p+m))`:
    /// block `i` is `−F̂_i x̂_1 + x̂_{i+1} + Ĝ_i u` (no `x̂_{n̂+1}` term for `i = n̂`).
    /// Also the general state step `x_{i+1|k} = Â x_{i|k} + B̂ u_{i|k}`. `x` and `out` have
    /// length `n̂p`, `u` length `m`.
    ///
    /// # Errors
    ///
    /// [`DimError`] for a slice of the wrong length.
    pub fn one_step_state(&self, x: &[f64], u: &[f64], out: &mut [f64]) -> Result<(), DimError> {
        let (n_hat, p, m) = (self.n_hat, self.p, self.m);
        check("x", x.len(), n_hat * p)?;
        check("u", u.len(), m)?;
        check("x_next", out.len(), n_hat * p)?;
        let (x_1, x_up) = x.split_at(p);
        for r in 0..p {
            let (fr, gr) = self.row(r);
            for b in 0..n_hat {
                // Block b + 1 (1-based): x̂_{b+2} (row r) if b + 1 < n̂, nothing for the last.
                let mut v = x_up.get(b * p + r).copied().unwrap_or(0.0);
                for (f, xs) in fr[b * p..][..p].iter().zip(x_1) {
                    v -= f * xs;
                }
                for (g, us) in gr[b * m..][..m].iter().zip(u) {
                    v += g * us;
                }
                out[b * p + r] = v;
            }
        }
        Ok(())
    }

    /// The Markov parameters `Ĥ_i = Ĉ Â^{i−1} B̂` of `T̂_{k,ℓ}` (2.46), `i = 1 … ℓ`, into `h`
    /// (`ℓ` blocks of `p × m` row-major, `ℓ = h.len() / (p m)`), by the recursion
    /// `Ĥ_i = Ĝ_i − Σ_{j=1}^{min(i−1, n̂)} F̂_j Ĥ_{i−j}` (`Ĝ_i = 0` for `i > n̂`), each entry
    /// summed over `j` ascending: `O(ℓ n̂ p² m)`, no dense power (module docs, "Cost").
    ///
    /// # Errors
    ///
    /// [`DimError`] when `h.len()` is not a multiple of `p m`.
    pub fn markov(&self, h: &mut [f64]) -> Result<(), DimError> {
        let (p, m) = (self.p, self.m);
        let blk = p * m;
        let ell = blocks("Markov parameters (a multiple of p·m)", h.len(), blk)?;
        for i in 1..=ell {
            let (done, rest) = h.split_at_mut((i - 1) * blk);
            let hi = &mut rest[..blk];
            for r0 in (0..p).step_by(TILE_ROWS) {
                for c0 in (0..m).step_by(TILE_COLS) {
                    let at = Tile { i, r0, c0 };
                    match ((p - r0).min(TILE_ROWS), (m - c0).min(TILE_COLS)) {
                        (4, 2) => self.markov_tile::<4, 2>(at, done, hi),
                        (4, _) => self.markov_tile::<4, 1>(at, done, hi),
                        (3, 2) => self.markov_tile::<3, 2>(at, done, hi),
                        (3, _) => self.markov_tile::<3, 1>(at, done, hi),
                        (2, 2) => self.markov_tile::<2, 2>(at, done, hi),
                        (2, _) => self.markov_tile::<2, 1>(at, done, hi),
                        (_, 2) => self.markov_tile::<1, 2>(at, done, hi),
                        _ => self.markov_tile::<1, 1>(at, done, hi),
                    }
                }
            }
        }
        Ok(())
    }

    /// The tile `at` (`R` rows, `C` columns) of `Ĥ_i` into `hi` (the block, `p × m`), from
    /// `Ĥ_1 … Ĥ_{i−1}` in `done`: the recursion seeded with `Ĝ_i`, `j` ascending.
    #[inline(always)]
    fn markov_tile<const R: usize, const C: usize>(&self, at: Tile, done: &[f64], hi: &mut [f64]) {
        let m = self.m;
        let mut seed = [[0.0; C]; R];
        if at.i <= self.n_hat {
            for (rr, s) in seed.iter_mut().enumerate() {
                s.copy_from_slice(&self.row(at.r0 + rr).1[(at.i - 1) * m + at.c0..][..C]);
            }
        }
        let acc = self.recursion_tile::<R, C, false>(at, m, seed, done);
        for (rr, a) in acc.iter().enumerate() {
            hi[(at.r0 + rr) * m + at.c0..][..C].copy_from_slice(a);
        }
    }

    /// The free response `Ĉ Â^{i−1} x_1`, `i = 1 … ℓ` (`Γ̂_{k,ℓ} x_{1|k}` of (2.43), (2.45)
    /// for `x_1 = x_{1|k}`), into `out` (`ℓ` blocks of `p`, `ℓ = out.len() / p`), by the
    /// recursion `y_i = x_{1,i} − Σ_{j=1}^{min(i−1, n̂)} F̂_j y_{i−j}` (`x_{1,i}` block `i` of
    /// `x_1`, zero for `i > n̂`), each entry summed over `j` descending, which is the order
    /// in which propagating `x ← Â x` adds the terms: `O(ℓ n̂ p²)` (module docs, "Cost").
    ///
    /// # Errors
    ///
    /// [`DimError`] for a slice of the wrong length.
    pub fn free_response(&self, x1: &[f64], out: &mut [f64]) -> Result<(), DimError> {
        let p = self.p;
        check("x_1", x1.len(), self.n_hat * p)?;
        let ell = blocks("free response (a multiple of p)", out.len(), p)?;
        for i in 1..=ell {
            let (done, rest) = out.split_at_mut((i - 1) * p);
            let yi = &mut rest[..p];
            for r0 in (0..p).step_by(TILE_ROWS) {
                let at = Tile { i, r0, c0: 0 };
                match (p - r0).min(TILE_ROWS) {
                    4 => self.free_tile::<4>(at, x1, done, yi),
                    3 => self.free_tile::<3>(at, x1, done, yi),
                    2 => self.free_tile::<2>(at, x1, done, yi),
                    _ => self.free_tile::<1>(at, x1, done, yi),
                }
            }
        }
        Ok(())
    }

    /// Rows `at.r0 .. at.r0+R` of `y_i` into `yi` (the block, length `p`), from
    /// `y_1 … y_{i−1}` in `done`: the recursion seeded with `x_{1,i}`, `j` descending.
    #[inline(always)]
    fn free_tile<const R: usize>(&self, at: Tile, x1: &[f64], done: &[f64], yi: &mut [f64]) {
        let p = self.p;
        let mut seed = [[0.0; 1]; R];
        if at.i <= self.n_hat {
            for (rr, s) in seed.iter_mut().enumerate() {
                s[0] = x1[(at.i - 1) * p + at.r0 + rr];
            }
        }
        let acc = self.recursion_tile::<R, 1, true>(at, 1, seed, done);
        for (rr, a) in acc.iter().enumerate() {
            yi[at.r0 + rr] = a[0];
        }
    }

    /// The companion recursion `Z_i = S_i − Σ_{j=1}^{min(i−1, n̂)} F̂_j Z_{i−j}` on one tile
    /// (`R` rows from `at.r0`, `C` columns from `at.c0`) of `Z_i` (`p × w`): `acc` holds the
    /// tile of the seed `S_i` and gets the sums, `done` holds `Z_1 … Z_{i−1}` (`p × w`
    /// row-major each). The `j` run ascending, or descending when `DOWN`; within a `j`, the
    /// columns `t` of `F̂_j` ascending. The `R·C` sums are independent, so they stay in
    /// registers and overlap instead of waiting on each other.
    #[inline(always)]
    fn recursion_tile<const R: usize, const C: usize, const DOWN: bool>(
        &self,
        at: Tile,
        w: usize,
        mut acc: [[f64; C]; R],
        done: &[f64],
    ) -> [[f64; C]; R] {
        let p = self.p;
        let jmax = (at.i - 1).min(self.n_hat);
        let f_rows: [&[f64]; R] = std::array::from_fn(|rr| &self.row(at.r0 + rr).0[..jmax * p]);
        // Index arithmetic rather than `chunks_exact` over the run-time `p` or `w`, whose
        // set-up divides.
        for jj in 0..jmax {
            // 0-based: F̂_{j+1} against Z_{i−1−j}.
            let j = if DOWN { jmax - 1 - jj } else { jj };
            let zj = &done[(at.i - 2 - j) * p * w..][..p * w];
            let fj: [&[f64]; R] = std::array::from_fn(|rr| &f_rows[rr][j * p..][..p]);
            for t in 0..p {
                let zt = &zj[t * w + at.c0..][..C];
                for (a, f) in acc.iter_mut().zip(&fj) {
                    let f = f[t];
                    for (a, z) in a.iter_mut().zip(zt) {
                        *a -= f * z;
                    }
                }
            }
        }
        acc
    }
}

/// The most rows of `Θ̃` one tile of the realization's recursions sums at once.
const TILE_ROWS: usize = 4;
/// The most columns of a Markov parameter one tile of [`Realization::markov`] sums at once.
const TILE_COLS: usize = 2;

/// Where a tile of a recursion lies: block `i` (1-based) of the result, first row `r0`,
/// first column `c0`.
#[derive(Debug, Clone, Copy)]
struct Tile {
    i: usize,
    r0: usize,
    c0: usize,
}

/// Pre-sized buffers for the quantities MPC needs at step `k` from an identified model:
/// `x̂_k` (2.38)–(2.39), `x_{1|k}` (2.36), `Ĥ_{k,1} … Ĥ_{k,ℓ}` (for `T̂_{k,ℓ}`,
/// (2.46)) and `Γ̂_{k,ℓ} x_{1|k}` (2.43), (2.45), computed together by
/// [`HorizonPrediction::compute`] (allocation-free). The predicted outputs for inputs
/// `U_{1|k,ℓ}` are then `y_{i|k} = (Γ̂ x_{1|k})_i + Σ_{j<i} Ĥ_{i−j} u_{j|k}`.
#[derive(Debug, Clone)]
pub struct HorizonPrediction {
    ell: usize,
    x_hat: Vec<f64>,
    x1: Vec<f64>,
    /// The other half of `x_{j|k} → x_{j+1|k}` in [`Self::compute_committed`].
    work: Vec<f64>,
    markov: Vec<f64>,
    free: Vec<f64>,
    /// [`Self::defer_horizon`].
    deferred: bool,
    /// How much of `markov` and `free` the last computation filled.
    markov_len: usize,
    free_len: usize,
}

/// The blocks of the free response a deferred computation fills
/// ([`HorizonPrediction::defer_horizon`]): `y` of the start and of one step on.
const HEAD_FREE_BLOCKS: usize = 2;

impl HorizonPrediction {
    /// Buffers for `model`'s dimensions and horizon `ℓ ≥ 1`.
    ///
    /// # Errors
    ///
    /// `ℓ = 0`.
    pub fn new<M: IdentifiedModel + ?Sized>(model: &M, ell: usize) -> Result<Self, String> {
        if ell == 0 {
            return Err("the horizon ell must be at least 1".into());
        }
        let real = model.realization();
        let (nx, p, m) = (real.state_dim(), real.p(), real.m());
        Ok(Self {
            ell,
            x_hat: vec![0.0; nx],
            x1: vec![0.0; nx],
            work: vec![0.0; nx],
            markov: vec![0.0; ell * p * m],
            free: vec![0.0; ell * p],
            deferred: false,
            markov_len: 0,
            free_len: 0,
        })
    }

    /// Whether the computations ([`Self::compute`], [`Self::compute_committed`],
    /// [`Self::compute_from_state`]) leave the horizon to [`Self::complete`]: with `true`
    /// they fill the states, `Ĥ_1` and the first two blocks of the free response only
    /// (what the one-step prediction of the signal log reads), which is all that the
    /// unconstrained fast path ([`crate::mpc::fast_path`]) needs when the problem has no
    /// output constraint; the rest, `O(ℓ n̂ p² (m + 1))`, only when a QP is condensed.
    /// Default `false`.
    pub fn defer_horizon(&mut self, deferred: bool) {
        self.deferred = deferred;
    }

    /// Whether the Markov parameters and the free response cover the whole horizon (false
    /// after a deferred computation until [`Self::complete`], and before any computation).
    pub fn is_complete(&self) -> bool {
        self.markov_len == self.markov.len() && self.free_len == self.free.len()
    }

    /// Fills the rest of a deferred computation: every Markov parameter and the whole free
    /// response from the start state already computed, for `real`, which must be the
    /// realization that computation used (the values are then bit for bit those of a
    /// computation that was not deferred). Nothing to do when already complete. Never
    /// allocates.
    ///
    /// # Errors
    ///
    /// [`DimError`] when `real`'s dimensions do not match the buffers.
    pub fn complete(&mut self, real: &Realization<'_>) -> Result<(), DimError> {
        if self.is_complete() {
            return Ok(());
        }
        check("realization state", real.state_dim(), self.x1.len())?;
        check(
            "markov buffer",
            self.markov.len(),
            self.ell * real.p() * real.m(),
        )?;
        self.fill_horizon(real, false)
    }

    /// The Markov parameters and the free response from `x_{1|k}` (`self.x1`): all `ℓ`
    /// blocks, or the head of [`Self::defer_horizon`] when `deferred`.
    fn fill_horizon(&mut self, real: &Realization<'_>, deferred: bool) -> Result<(), DimError> {
        let (markov_len, free_len) = if deferred {
            let p = real.p();
            (p * real.m(), (HEAD_FREE_BLOCKS * p).min(self.free.len()))
        } else {
            (self.markov.len(), self.free.len())
        };
        self.markov_len = 0;
        self.free_len = 0;
        real.markov(&mut self.markov[..markov_len])?;
        real.free_response(&self.x1, &mut self.free[..free_len])?;
        self.markov_len = markov_len;
        self.free_len = free_len;
        Ok(())
    }

    /// Step `k`, after the model's identification step: fills `x̂_k`,
    /// `x_{1|k} = Â x̂_k + B̂ u_k` (`u_k`: the input of the current period, length `m`), the
    /// Markov parameters and the free response from the current coefficients `θ_{k+1}`.
    /// Never allocates.
    ///
    /// # Errors
    ///
    /// [`DimError`] when `u_k` or the model's dimensions do not match the buffers.
    pub fn compute<M: IdentifiedModel + ?Sized>(
        &mut self,
        model: &M,
        u_k: &[f64],
    ) -> Result<(), DimError> {
        let real = self.fill_state(model)?;
        real.one_step_state(&self.x_hat, u_k, &mut self.x1)?;
        self.fill_horizon(&real, self.deferred)
    }

    /// Step `k` for a plan that starts `d` samples later (PCAC's multi-rate re-planning,
    /// [`crate::pcac::PcacParams::replan_every`]): the inputs `u_k, …, u_{k+d−1}` are
    /// already committed (`committed`, `d ≥ 1` rows of `m`), so the state the new plan
    /// starts from is the `d`-step prediction
    ///
    /// ```text
    /// x_{1|k} = Â_k x̂_k + B̂_k u_k,   x_{j+1|k} = Â_k x_{j|k} + B̂_k u_{k+j},  j = 1 … d−1
    /// ```
    ///
    /// ((2.36) repeated), and the free response is `Ĉ Â_k^{i−1} x_{d|k}`, `i = 1 … ℓ`: the
    /// outputs `y_{d|k}, …, y_{d+ℓ−1|k}` for zero inputs from `u_{k+d}` on. The Markov
    /// parameters do not depend on the start. [`Self::one_step_state`] is then `x_{d|k}`.
    /// With `d = 1` this is [`Self::compute`], bit for bit. `O(d n̂ p (p+m))` more than
    /// it; never allocates.
    ///
    /// # Errors
    ///
    /// [`DimError`] when `committed` is empty or not a multiple of `m`, or the model's
    /// dimensions do not match the buffers.
    pub fn compute_committed<M: IdentifiedModel + ?Sized>(
        &mut self,
        model: &M,
        committed: &[f64],
    ) -> Result<(), DimError> {
        let real = self.fill_state(model)?;
        let m = real.m();
        let d = blocks("committed inputs (a multiple of m)", committed.len(), m)?;
        if d == 0 {
            return Err(DimError {
                what: "committed inputs (at least one row)",
                expected: m,
                got: 0,
            });
        }
        real.one_step_state(&self.x_hat, &committed[..m], &mut self.x1)?;
        for u in committed.chunks_exact(m).skip(1) {
            real.one_step_state(&self.x1, u, &mut self.work)?;
            std::mem::swap(&mut self.x1, &mut self.work);
        }
        self.fill_horizon(&real, self.deferred)
    }

    /// Step `k`, after the model's identification step, for an input `u_k` still to be
    /// chosen (PCAC's same-step timing): fills `x̂_k`, the Markov parameters and the free
    /// response `Ĉ Â_k^{i−1} x̂_k`, `i = 1 … ℓ` (the outputs `y_k, ŷ_{k+1}, …, ŷ_{k+ℓ−1}`
    /// for zero inputs from `u_k` on; the first block is `y_k`). [`Self::one_step_state`]
    /// is then `x̂_k` as well. Never allocates.
    ///
    /// # Errors
    ///
    /// [`DimError`] when the model's dimensions do not match the buffers.
    pub fn compute_from_state<M: IdentifiedModel + ?Sized>(
        &mut self,
        model: &M,
    ) -> Result<(), DimError> {
        let real = self.fill_state(model)?;
        self.x1.copy_from_slice(&self.x_hat);
        self.fill_horizon(&real, self.deferred)
    }

    /// The start of both computations: checks the buffers against the model's
    /// dimensions, fills `x̂_k` and returns the realization.
    fn fill_state<'m, M: IdentifiedModel + ?Sized>(
        &mut self,
        model: &'m M,
    ) -> Result<Realization<'m>, DimError> {
        let real = model.realization();
        check(
            "markov buffer",
            self.markov.len(),
            self.ell * real.p() * real.m(),
        )?;
        real.fill_state(model, &mut self.x_hat)?;
        Ok(real)
    }

    /// The horizon `ℓ`.
    pub fn horizon(&self) -> usize {
        self.ell
    }

    /// `x̂_k` (length `n̂p`).
    pub fn state(&self) -> &[f64] {
        &self.x_hat
    }

    /// `x_{1|k}` (length `n̂p`).
    pub fn one_step_state(&self) -> &[f64] {
        &self.x1
    }

    /// `Ĥ_{k,1} … Ĥ_{k,ℓ}` (`ℓ` blocks `p × m`, row-major; [`crate::mpc`]'s condensing
    /// uses the first `ℓ − 1`): the blocks the last computation filled, all of them unless
    /// it was deferred ([`Self::defer_horizon`], [`Self::is_complete`]); none before the
    /// first. A computation refused for its arguments' dimensions leaves them as they were.
    pub fn markov(&self) -> &[f64] {
        &self.markov[..self.markov_len]
    }

    /// `Γ̂_{k,ℓ} x_{1|k}` = `y_{1|k} … y_{ℓ|k}` for `U = 0` (`ℓ` blocks of `p`): the blocks
    /// the last computation filled, as for [`Self::markov`].
    pub fn free_response(&self) -> &[f64] {
        &self.free[..self.free_len]
    }
}

#[cfg(test)]
mod tests {
    //! The realization against dense matrix powers and against the input–output model
    //! (2.24) it realizes (PCAC's [`IoModel`], used here as the source of coefficients and
    //! data).

    #![allow(clippy::needless_range_loop)] // index-heavy reference computations

    use nalgebra::{DMatrix, DVector};

    use super::{DataWindow, DimError, HorizonPrediction, Realization};
    use crate::forgetting::ForgettingRule;
    use crate::pcac::{IdKernel, IoModel, IoModelParams};
    use crate::test_support::{Gauss, io_model_params, max_abs, max_abs_diff};

    fn params(n_hat: usize, p: usize, m: usize) -> IoModelParams {
        let rule = ForgettingRule::Constant { lambda: 1.0 };
        io_model_params(n_hat, p, m, rule, IdKernel::Shared)
    }

    /// A model with random coefficients `θ_0` (no identification) and random histories.
    fn random_model(g: &mut Gauss, n: usize, p: usize, m: usize) -> IoModel {
        let mut pr = params(n, p, m);
        pr.theta0 = g.vec(n * p * (p + m)).iter().map(|x| 0.4 * x).collect();
        let mut model = IoModel::new(&pr).unwrap();
        for _ in 0..(n + 3) {
            model.observe(&g.vec(p), &g.vec(m)).unwrap();
        }
        model
    }

    #[test]
    fn the_realization_predicts_like_the_input_output_model() {
        let mut g = Gauss::new(31);
        let (mut d1, mut dl, mut dh, mut df): (f64, f64, f64, f64) = (0.0, 0.0, 0.0, 0.0);
        for (n, p, m) in [(4, 3, 2), (1, 2, 1), (3, 1, 3), (5, 4, 2)] {
            let model = random_model(&mut g, n, p, m);
            let nx = n * p;
            let (mut a, mut b, mut xh) = (vec![0.0; nx * nx], vec![0.0; nx * m], vec![0.0; nx]);
            let real = model.realization();
            real.fill_a(&mut a).unwrap();
            real.fill_b(&mut b).unwrap();
            real.fill_state(&model, &mut xh).unwrap();
            let a_m = DMatrix::from_row_slice(nx, nx, &a);
            let b_m = DMatrix::from_row_slice(nx, m, &b);
            let c_m = DMatrix::from_fn(p, nx, |i, j| f64::from(u8::from(i == j)));

            // One step: Ĉ (Â x̂ + B̂ u_k) = (2.24)'s prediction of y_{k+1}; structured = dense.
            let u_k = g.vec(m);
            let x1_dense =
                &a_m * DVector::from_column_slice(&xh) + &b_m * DVector::from_column_slice(&u_k);
            let mut x1 = vec![0.0; nx];
            real.one_step_state(&xh, &u_k, &mut x1).unwrap();
            d1 = d1.max(max_abs_diff(&x1, x1_dense.as_slice()));
            let mut yhat = vec![0.0; p];
            model.predict_one_step(&u_k, &mut yhat).unwrap();
            d1 = d1.max(max_abs_diff(&x1[..p], &yhat));
            // Ĉ x̂_k = y_k (2.37).
            assert!(
                (&c_m * DVector::from_column_slice(&xh))
                    .iter()
                    .zip(&xh[..p])
                    .all(|(a, b)| a == b)
            );

            // ℓ steps: iterate the state with future inputs vs recursing (2.24) on predictions.
            let ell = 9;
            let fut: Vec<Vec<f64>> = (0..ell).map(|_| g.vec(m)).collect();
            let nr = n * (p + m);
            let coef = model.coefficients();
            // (2.24) recursed on its own predictions: a copy of the model predicts ŷ_{k+1+i}
            // and then stores it as if measured, with u_k, u_{1|k}, u_{2|k}, ….
            let mut rec = model.clone();
            let mut y_rec = Vec::new();
            let mut u_now = u_k.clone();
            for i in 0..ell {
                let mut y = vec![0.0; p];
                rec.predict_one_step(&u_now, &mut y).unwrap();
                rec.observe(&y, &u_now).unwrap();
                y_rec.push(y);
                if i + 1 < ell {
                    u_now = fut[i].clone();
                }
            }
            // State iteration: y_{i|k} = Ĉ x_{i|k}, x_{i+1|k} = Â x_{i|k} + B̂ u_{i|k}.
            let mut x = x1.clone();
            let mut y_state = Vec::new();
            for u in &fut {
                y_state.push(x[..p].to_vec());
                let mut nxt = vec![0.0; nx];
                real.one_step_state(&x, u, &mut nxt).unwrap();
                x = nxt;
            }
            for i in 0..ell {
                dl = dl.max(max_abs_diff(&y_rec[i], &y_state[i]) / (1.0 + max_abs(&y_rec[i])));
            }
            // (2.43): Y = Γ̂ x_{1|k} + T̂ U with the fast Markov parameters and free response.
            let mut h = vec![0.0; (ell + 3) * p * m];
            real.markov(&mut h).unwrap();
            let mut free = vec![0.0; ell * p];
            real.free_response(&x1, &mut free).unwrap();
            for i in 0..ell {
                let mut y = free[i * p..(i + 1) * p].to_vec();
                for j in 0..i {
                    // T̂ block (i, j) = Ĥ_{i−j}, u_{j+1|k} = fut[j].
                    let hb = &h[(i - j - 1) * p * m..(i - j) * p * m];
                    for r in 0..p {
                        for s in 0..m {
                            y[r] += hb[r * m + s] * fut[j][s];
                        }
                    }
                }
                dl = dl.max(max_abs_diff(&y, &y_rec[i]) / (1.0 + max_abs(&y_rec[i])));
            }
            // The bundled computation gives the same numbers.
            let mut hp = HorizonPrediction::new(&model, ell).unwrap();
            hp.compute(&model, &u_k).unwrap();
            assert_eq!(hp.state(), &xh[..]);
            assert_eq!(hp.one_step_state(), &x1[..]);
            assert_eq!(hp.markov(), &h[..ell * p * m]);
            assert_eq!(hp.free_response(), &free[..]);
            assert!(hp.compute(&model, &vec![0.0; m + 1]).is_err());
            // Committed inputs: one row is `compute` bit for bit; three start the free
            // response at x_{3|k}, whose output is the recursive prediction of y_{k+3}.
            let mut hc = HorizonPrediction::new(&model, ell).unwrap();
            hc.compute_committed(&model, &u_k).unwrap();
            assert_eq!(hc.one_step_state(), hp.one_step_state());
            assert_eq!(hc.free_response(), hp.free_response());
            assert_eq!(hc.markov(), hp.markov());
            if ell >= 3 {
                let committed: Vec<f64> =
                    u_k.iter().chain(&fut[0]).chain(&fut[1]).copied().collect();
                hc.compute_committed(&model, &committed).unwrap();
                assert_eq!(hc.markov(), hp.markov());
                for i in 0..ell - 2 {
                    let mut want = y_rec[i + 2].clone();
                    // y_rec continues with the planned inputs fut[2..]; take them out.
                    for j in 0..i {
                        let hb = &h[(i - j - 1) * p * m..(i - j) * p * m];
                        for r in 0..p {
                            for s in 0..m {
                                want[r] -= hb[r * m + s] * fut[j + 2][s];
                            }
                        }
                    }
                    let got = &hc.free_response()[i * p..(i + 1) * p];
                    dl = dl.max(max_abs_diff(got, &want) / (1.0 + max_abs(&want)));
                }
            }
            assert!(hc.compute_committed(&model, &[]).is_err());
            if m > 1 {
                assert!(hc.compute_committed(&model, &vec![0.0; m + 1]).is_err());
            }
            // Markov parameters and free response against dense powers.
            let mut apow = DMatrix::<f64>::identity(nx, nx);
            let x1v = DVector::from_column_slice(&x1);
            for i in 1..=ell + 3 {
                let hd = &c_m * &apow * &b_m;
                let hb = &h[(i - 1) * p * m..i * p * m];
                let hd_rows: Vec<f64> = (0..p)
                    .flat_map(|r| (0..m).map(move |s| (r, s)))
                    .map(|rs| hd[rs])
                    .collect();
                dh = dh.max(max_abs_diff(hb, &hd_rows) / (1.0 + max_abs(&hd_rows)));
                if i <= ell {
                    let fd = &c_m * &apow * &x1v;
                    df = df.max(
                        max_abs_diff(&free[(i - 1) * p..i * p], fd.as_slice()) / (1.0 + fd.amax()),
                    );
                }
                apow = &apow * &a_m;
            }
            // Â, B̂ hold the coefficients where (2.40)–(2.41) put them.
            for i in 1..=n {
                for r in 0..p {
                    for s in 0..p {
                        assert_eq!(a_m[((i - 1) * p + r, s)], -coef[r * nr + (i - 1) * p + s]);
                    }
                    for s in 0..m {
                        assert_eq!(
                            b_m[((i - 1) * p + r, s)],
                            coef[r * nr + n * p + (i - 1) * m + s]
                        );
                    }
                }
            }
        }
        assert!(d1 < 1e-12, "one-step prediction differs by {d1}");
        assert!(dl < 1e-10, "ℓ-step prediction differs by {dl}");
        assert!(dh < 1e-10, "Markov parameters differ by {dh}");
        assert!(df < 1e-10, "free response differs by {df}");
        eprintln!(
            "realization: one-step {d1:.1e}, ℓ-step {dl:.1e}, Markov {dh:.1e}, free {df:.1e}"
        );
    }

    #[test]
    fn the_state_uses_the_data_of_2_39() {
        // x̂_k from (2.39) written out with explicit data, n̂ = 3, p = 2, m = 1.
        let (n, p, m) = (3, 2, 1);
        let mut g = Gauss::new(41);
        let mut pr = params(n, p, m);
        pr.theta0 = g.vec(n * p * (p + m));
        let mut model = IoModel::new(&pr).unwrap();
        // Steps k = 0 … 5: update(y_k, u_{k−1}) with stored histories.
        let ys: Vec<Vec<f64>> = (0..6).map(|_| g.vec(p)).collect();
        let us: Vec<Vec<f64>> = (0..6).map(|_| g.vec(m)).collect();
        for k in 0..6 {
            let u_prev = if k == 0 {
                vec![0.0; m]
            } else {
                us[k - 1].clone()
            };
            model.observe(&ys[k], &u_prev).unwrap();
        }
        let k = 5;
        let mut x = vec![0.0; n * p];
        model.realization().fill_state(&model, &mut x).unwrap();
        let mut want = vec![0.0; n * p];
        want[..p].copy_from_slice(&ys[k]);
        for i in 2..=n {
            for r in 0..p {
                let mut v = 0.0;
                for j in 1..=n - i + 1 {
                    for s in 0..p {
                        v -= model.f(i + j - 1, r, s) * ys[k - j][s];
                    }
                    for s in 0..m {
                        v += model.g(i + j - 1, r, s) * us[k - j][s];
                    }
                }
                want[(i - 1) * p + r] = v;
            }
        }
        assert!(max_abs_diff(&x, &want) < 1e-14);
    }

    /// The plain loops of (2.39), of the Markov recursion and of the state propagation
    /// `x ← Â x`, summing in the order the tiled kernels keep: the state with `j`
    /// ascending, `F̂` before `Ĝ`; `Ĥ_i` with `j` ascending; the free response as the
    /// propagation adds its terms.
    struct Plain<'a>(Realization<'a>);

    impl Plain<'_> {
        fn state(&self, model: &IoModel, x: &mut [f64]) {
            let (r, n, p, m) = (&self.0, self.0.n_hat(), self.0.p(), self.0.m());
            x[..p].copy_from_slice(model.past_output(0));
            for i in 2..=n {
                for row in 0..p {
                    let mut v = 0.0;
                    for j in 1..=n - i + 1 {
                        let (y, u) = (model.past_output(j), model.past_input(j));
                        for s in 0..p {
                            v -= r.f(i + j - 1, row, s) * y[s];
                        }
                        for s in 0..m {
                            v += r.g(i + j - 1, row, s) * u[s];
                        }
                    }
                    x[(i - 1) * p + row] = v;
                }
            }
        }

        fn markov(&self, h: &mut [f64]) {
            let (r, n, p, m) = (&self.0, self.0.n_hat(), self.0.p(), self.0.m());
            let blk = p * m;
            for i in 1..=h.len() / blk {
                for row in 0..p {
                    for s in 0..m {
                        let mut v = if i <= n { r.g(i, row, s) } else { 0.0 };
                        for j in 1..=(i - 1).min(n) {
                            for t in 0..p {
                                v -= r.f(j, row, t) * h[(i - j - 1) * blk + t * m + s];
                            }
                        }
                        h[(i - 1) * blk + row * m + s] = v;
                    }
                }
            }
        }

        fn free_response(&self, x1: &[f64], out: &mut [f64]) {
            let (r, n, p) = (&self.0, self.0.n_hat(), self.0.p());
            let mut x = x1.to_vec();
            for i in 0..out.len() / p {
                let y = x[..p].to_vec();
                out[i * p..(i + 1) * p].copy_from_slice(&y);
                for b in 1..=n {
                    for row in 0..p {
                        let mut v = if b < n { x[b * p + row] } else { 0.0 };
                        for s in 0..p {
                            v -= r.f(b, row, s) * y[s];
                        }
                        x[(b - 1) * p + row] = v;
                    }
                }
            }
        }
    }

    #[test]
    fn the_tiled_kernels_equal_the_plain_loops_bit_for_bit() {
        // p from 1 to 9 covers every tile height (4-row tiles and a last one of 1, 2 or 3
        // rows) and m from 1 to 5 every tile width (2-column tiles and a last one of 1);
        // the truss (25, 4, 2) and the arm (1, 5, 2) are among them. ℓ below, at and
        // beyond n̂.
        let mut g = Gauss::new(53);
        let shapes = [
            (25, 4, 2, 40),
            (1, 5, 2, 50),
            (1, 1, 1, 3),
            (2, 2, 1, 1),
            (3, 3, 3, 7),
            (4, 6, 5, 9),
            (5, 7, 2, 4),
            (3, 8, 4, 12),
            (6, 9, 1, 8),
            (2, 5, 3, 6),
        ];
        for (n, p, m, ell) in shapes {
            let mut model = random_model(&mut g, n, p, m);
            let plain = Plain(model.realization());
            let (mut x, mut x_ref) = (vec![0.0; n * p], vec![1.0; n * p]);
            model.realization().fill_state(&model, &mut x).unwrap();
            plain.state(&model, &mut x_ref);
            assert_eq!(x, x_ref, "state, shape {n} {p} {m}");
            let (mut h, mut h_ref) = (vec![0.0; ell * p * m], vec![1.0; ell * p * m]);
            model.realization().markov(&mut h).unwrap();
            plain.markov(&mut h_ref);
            assert_eq!(h, h_ref, "Markov parameters, shape {n} {p} {m} {ell}");
            let (mut f, mut f_ref) = (vec![0.0; ell * p], vec![1.0; ell * p]);
            model.realization().free_response(&x, &mut f).unwrap();
            plain.free_response(&x, &mut f_ref);
            assert_eq!(f, f_ref, "free response, shape {n} {p} {m} {ell}");
            // The bundle computes the same (from x̂_k here, same-step timing).
            let mut hp = HorizonPrediction::new(&model, ell).unwrap();
            hp.compute_from_state(&model).unwrap();
            assert_eq!((hp.markov(), hp.free_response()), (&h[..], &f[..]));
            // Identified coefficients as well as random ones: one update, then again.
            model.update(&g.vec(p), &g.vec(m)).unwrap();
            let plain = Plain(model.realization());
            model.realization().markov(&mut h).unwrap();
            plain.markov(&mut h_ref);
            assert_eq!(
                h, h_ref,
                "Markov parameters after an update, shape {n} {p} {m}"
            );
        }
    }

    #[test]
    fn a_realization_built_from_coefficients_equals_the_models_own() {
        let mut g = Gauss::new(37);
        let (n, p, m) = (3, 2, 2);
        let model = random_model(&mut g, n, p, m);
        let own = model.realization();
        let built = Realization::new(n, p, m, model.coefficients()).unwrap();
        assert_eq!((built.n_hat(), built.p(), built.m()), (n, p, m));
        assert_eq!(built.state_dim(), n * p);
        let (mut h1, mut h2) = (vec![0.0; 7 * p * m], vec![0.0; 7 * p * m]);
        own.markov(&mut h1).unwrap();
        built.markov(&mut h2).unwrap();
        assert_eq!(h1, h2);
        let (mut x1, mut x2) = (vec![0.0; n * p], vec![0.0; n * p]);
        own.fill_state(&model, &mut x1).unwrap();
        built.fill_state(&model, &mut x2).unwrap();
        assert_eq!(x1, x2);
        for i in 1..=n {
            assert_eq!(built.f(i, 1, 0), model.f(i, 1, 0));
            assert_eq!(built.g(i, 0, 1), model.g(i, 0, 1));
        }
    }

    /// A deferred prediction fills the states, `Ĥ_1` and two blocks of the free response;
    /// completed on the same realization it equals the prediction that was not deferred,
    /// bit for bit, in all three computations; a realization of other dimensions is
    /// refused.
    #[test]
    fn a_deferred_horizon_completed_equals_the_whole_prediction() {
        let mut g = Gauss::new(8);
        for (n, p, m, ell) in [(1, 5, 2, 50), (3, 2, 2, 9), (2, 1, 1, 1)] {
            let model = random_model(&mut g, n, p, m);
            let (u_k, committed) = (g.vec(m), g.vec(3 * m));
            let run = |defer: bool, which: usize| {
                let mut hp = HorizonPrediction::new(&model, ell).unwrap();
                hp.defer_horizon(defer);
                assert!(!hp.is_complete());
                match which {
                    0 => hp.compute(&model, &u_k),
                    1 => hp.compute_committed(&model, &committed),
                    _ => hp.compute_from_state(&model),
                }
                .unwrap();
                hp
            };
            for which in 0..3 {
                let whole = run(false, which);
                assert!(whole.is_complete());
                assert_eq!(whole.markov().len(), ell * p * m);
                let mut part = run(true, which);
                assert_eq!(part.is_complete(), ell == 1 && p * m == part.markov().len());
                assert_eq!(part.one_step_state(), whole.one_step_state());
                assert_eq!(part.markov(), &whole.markov()[..p * m]);
                let head = (2 * p).min(ell * p);
                assert_eq!(part.free_response(), &whole.free_response()[..head]);
                let other = random_model(&mut g, n, p + 1, m);
                if !part.is_complete() {
                    assert!(part.complete(&other.realization()).is_err());
                    assert!(!part.is_complete());
                }
                part.complete(&model.realization()).unwrap();
                assert!(part.is_complete());
                assert_eq!(part.markov(), whole.markov());
                assert_eq!(part.free_response(), whole.free_response());
            }
        }
    }

    #[test]
    fn wrong_dimensions_and_lengths_are_refused_without_change() {
        let coef = vec![0.5; 3 * 2 * 3];
        assert_eq!(
            Realization::new(3, 2, 1, &coef[..17]).unwrap_err(),
            DimError {
                what: "coefficients",
                expected: 18,
                got: 17
            }
        );
        assert!(Realization::new(0, 2, 1, &[]).is_err());
        assert!(Realization::new(3, 0, 1, &[]).is_err());
        assert!(Realization::new(3, 2, 0, &coef[..12]).is_err());
        let real = Realization::new(3, 2, 1, &coef).unwrap();
        let mut a = [7.0; 35];
        assert_eq!(
            real.fill_a(&mut a).unwrap_err().to_string(),
            "A has length 35, expected 36"
        );
        assert!(
            a.iter().all(|&v| v == 7.0),
            "a refused call must change nothing"
        );
        assert!(real.fill_a(&mut [0.0; 36]).is_ok());
        assert!(real.fill_b(&mut [0.0; 5]).is_err());
        assert!(real.fill_b(&mut [0.0; 6]).is_ok());
        assert!(real.markov(&mut [0.0; 5]).is_err());
        assert!(real.markov(&mut [0.0; 6]).is_ok());
        assert!(real.free_response(&[0.0; 6], &mut [0.0; 5]).is_err());
        assert!(real.free_response(&[0.0; 5], &mut [0.0; 6]).is_err());
        assert!(
            real.one_step_state(&[0.0; 6], &[0.0; 2], &mut [0.0; 6])
                .is_err()
        );
        let model = IoModel::new(&params(3, 2, 1)).unwrap();
        assert!(
            model
                .realization()
                .fill_state(&model, &mut [0.0; 5])
                .is_err()
        );
        let e = HorizonPrediction::new(&model, 0).unwrap_err();
        assert!(e.contains("horizon"), "{e}");
    }
}
