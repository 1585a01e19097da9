//! # Linear time-invariant models
//!
//! Continuous-time and discrete-time LTI models, their realization and their exact
//! sampled-data discretization.
//!
//! ## Transfer functions
//!
//! A [`Tf`] is a ratio of polynomials with coefficients in descending powers of the
//! variable (`s` for a continuous model, `z` for a discrete one; the type does not care):
//!
//! ```text
//!          b_0 p^m + b_1 p^(m-1) + ... + b_m
//! G(p) = -------------------------------------,   a_0 ≠ 0,  m ≤ n (proper).
//!          a_0 p^n + a_1 p^(n-1) + ... + a_n
//! ```
//!
//! ## State-space models
//!
//! A [`StateSpace`] holds `(A, B, C, D)`. Whether it is continuous,
//! `ẋ = A x + B u, y = C x + D u`, or discrete, `x_{k+1} = A x_k + B u_k, y_k = C x_k + D u_k`
//! (then `A = Φ`, `B = Γ`), is known from the context that built it: [`Tf::realize`] and
//! [`realize_tf_matrix`] give a model of the same kind as their transfer functions,
//! [`StateSpace::c2d_zoh`] turns a continuous model into a discrete one. Its transfer
//! matrix is `G(p) = C (pI − A)^{-1} B + D` in both cases ([`StateSpace::freq_response`]).
//!
//! ## Realization
//!
//! A proper SISO transfer function is realized in controllable canonical form: with the
//! denominator made monic (`a_0 = 1`) and the numerator padded to degree `n`
//! (`b_0 … b_n`), the direct feedthrough is `D = b_0` and the strictly proper remainder
//! has numerator coefficients `c_i = b_i − b_0 a_i`, `i = 1 … n`:
//!
//! ```text
//!     ⎡ −a_1  −a_2  …  −a_{n−1}  −a_n ⎤        ⎡1⎤
//!     ⎢   1     0   …     0        0  ⎥        ⎢0⎥
//! A = ⎢   0     1   …     0        0  ⎥,   B = ⎢⋮⎥,   C = [c_1 … c_n],   D = b_0.
//!     ⎢   ⋮            ⋱           ⋮  ⎥        ⎢⋮⎥
//!     ⎣   0     0   …     1        0  ⎦        ⎣0⎦
//! ```
//!
//! A matrix of transfer functions (rows = outputs, columns = inputs) is realized column by
//! column ([`realize_tf_matrix`]): when every nonzero entry of a column has the same monic
//! denominator, the column is realized once with one output row per entry (the rows of `C`
//! differ, `A` and `B` are shared); otherwise each entry gets its own realization. The
//! blocks are stacked block-diagonally, so the result is exact but may be non-minimal.
//!
//! ## Zero-order-hold discretization
//!
//! With the input held constant over each sample period `T`, the exact discretization is
//! read from one matrix exponential of the augmented matrix ([`c2d_zoh`]):
//!
//! ```text
//!      ⎛⎡A  B⎤   ⎞   ⎡Φ  Γ⎤                                  T
//!  exp ⎜⎢    ⎥ T ⎟ = ⎢    ⎥,   Φ = e^{AT},   Γ = ∫ e^{Aτ} dτ B,
//!      ⎝⎣0  0⎦   ⎠   ⎣0  I⎦                                  0
//! ```
//!
//! as used for (3.42), the discretization of (3.41) at `T_s = 0.01 s`.
//!
//! ## Transfer-function coefficients of a state-space channel
//!
//! For the channel `(i, j)` of `(A, B, C, D)` ([`StateSpace::channel_tf`]) the states that
//! the input cannot reach or that the output cannot see (judged from the sparsity of `A`,
//! `B`, `C`: an exact structural reduction) are removed first. Then
//!
//! - the denominator is the characteristic polynomial `det(pI − A) = ∏ (p − λ_i)`, expanded
//!   from the eigenvalues `λ_i` of `A`, computed by the real Schur form (Hessenberg
//!   reduction and the implicit double-shift QR iteration): backward stable, and the
//!   eigenvalues are the poles reported next to the coefficients;
//! - the numerator follows from the Markov parameters `h_0 = D`, `h_k = C A^{k−1} B`
//!   ([`StateSpace::markov_parameters`]): since `G(p) a(p) = b(p)` and
//!   `G(p) = Σ_k h_k p^{−k}`, the numerator coefficients are `b_k = Σ_{i=0}^{k} a_i h_{k−i}`,
//!   `k = 0 … n`. Their rounding errors scale with the size of `h`, unlike the difference
//!   `det(pI − A + B C) − det(pI − A)`, whose errors do not shrink with a small gain.
//!
//! The Markov parameters of a discrete model are its impulse response.

pub mod generalized;

pub use generalized::{ChannelDims, GeneralizedPlant, Mode};

use nalgebra::{Complex, DMatrix, linalg::Schur};
use std::fmt;

/// Why an LTI model or an operation on it was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum LtiError {
    /// The denominator has no coefficient.
    EmptyDenominator,
    /// The leading denominator coefficient is zero (the degree would be ambiguous).
    ZeroLeadingDenominator,
    /// The numerator degree exceeds the denominator degree: the transfer function is not
    /// proper and has no state-space realization.
    Improper {
        /// Degree of the numerator (after dropping leading zeros).
        num_degree: usize,
        /// Degree of the denominator.
        den_degree: usize,
    },
    /// A coefficient or matrix entry is NaN or infinite.
    NonFinite {
        /// Which coefficient vector or matrix.
        what: String,
    },
    /// A matrix has the wrong dimensions.
    Dimension {
        /// Which matrix.
        what: String,
        /// Expected `(rows, columns)`.
        expected: (usize, usize),
        /// Found `(rows, columns)`.
        found: (usize, usize),
    },
    /// A row of a transfer-function matrix has another length than the first row.
    RaggedRow {
        /// Index of the row.
        row: usize,
        /// Its length.
        len: usize,
        /// The expected length.
        expected: usize,
    },
    /// A channel index is out of range.
    Channel {
        /// Requested output.
        output: usize,
        /// Requested input.
        input: usize,
        /// `(outputs, inputs)` of the model.
        size: (usize, usize),
    },
    /// The sample period is not positive and finite.
    SamplePeriod(f64),
    /// A numerical step failed (overflow of the matrix exponential, no convergence of the
    /// eigenvalue iteration, a singular matrix at an evaluation point).
    Numerical(String),
}

impl fmt::Display for LtiError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LtiError::EmptyDenominator => write!(f, "the denominator has no coefficient"),
            LtiError::ZeroLeadingDenominator => {
                write!(f, "the leading denominator coefficient is zero")
            }
            LtiError::Improper {
                num_degree,
                den_degree,
            } => write!(
                f,
                "improper transfer function: numerator degree {num_degree} exceeds denominator degree {den_degree}"
            ),
            LtiError::NonFinite { what } => write!(f, "{what} has a NaN or infinite value"),
            LtiError::Dimension {
                what,
                expected,
                found,
            } => write!(
                f,
                "{what} is {}×{}, expected {}×{}",
                found.0, found.1, expected.0, expected.1
            ),
            LtiError::RaggedRow { row, len, expected } => write!(
                f,
                "row {row} has {len} entries, expected {expected} (one per input)"
            ),
            LtiError::Channel {
                output,
                input,
                size,
            } => write!(
                f,
                "channel ({output}, {input}) does not exist in a model with {} outputs and {} inputs",
                size.0, size.1
            ),
            LtiError::SamplePeriod(t) => {
                write!(f, "sample period {t} is not positive and finite")
            }
            LtiError::Numerical(m) => write!(f, "numerical failure: {m}"),
        }
    }
}

impl std::error::Error for LtiError {}

fn check_finite(what: &str, v: &[f64]) -> Result<(), LtiError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(LtiError::NonFinite {
            what: what.to_string(),
        })
    }
}

fn check_dims(what: &str, m: &DMatrix<f64>, rows: usize, cols: usize) -> Result<(), LtiError> {
    if m.nrows() != rows || m.ncols() != cols {
        return Err(LtiError::Dimension {
            what: what.to_string(),
            expected: (rows, cols),
            found: (m.nrows(), m.ncols()),
        });
    }
    check_finite(what, m.as_slice())
}

/// A proper SISO transfer function `num(p)/den(p)`, coefficients in descending powers of
/// `p` (`s` or `z`).
///
/// Invariants (checked by [`Tf::new`]): every coefficient is finite, the denominator is
/// non-empty with a nonzero leading coefficient, and the numerator degree (leading zeros
/// ignored) does not exceed the denominator degree.
#[derive(Debug, Clone, PartialEq)]
pub struct Tf {
    num: Vec<f64>,
    den: Vec<f64>,
}

impl Tf {
    /// A validated transfer function. Leading zeros of the numerator are dropped; an empty
    /// numerator is the zero transfer function.
    pub fn new(num: Vec<f64>, den: Vec<f64>) -> Result<Self, LtiError> {
        check_finite("the numerator", &num)?;
        check_finite("the denominator", &den)?;
        if den.is_empty() {
            return Err(LtiError::EmptyDenominator);
        }
        if den[0] == 0.0 {
            return Err(LtiError::ZeroLeadingDenominator);
        }
        let first = num.iter().position(|&b| b != 0.0);
        let num = match first {
            Some(i) => num[i..].to_vec(),
            None => vec![0.0],
        };
        let (num_degree, den_degree) = (num.len() - 1, den.len() - 1);
        if num_degree > den_degree {
            return Err(LtiError::Improper {
                num_degree,
                den_degree,
            });
        }
        Ok(Self { num, den })
    }

    /// Numerator coefficients, descending powers, without leading zeros (`[0.0]` when zero).
    pub fn num(&self) -> &[f64] {
        &self.num
    }

    /// Denominator coefficients, descending powers, leading coefficient nonzero.
    pub fn den(&self) -> &[f64] {
        &self.den
    }

    /// Degree of the numerator (0 for the zero transfer function).
    pub fn num_degree(&self) -> usize {
        self.num.len() - 1
    }

    /// Degree of the denominator: the order of the realization [`Tf::realize`].
    pub fn den_degree(&self) -> usize {
        self.den.len() - 1
    }

    /// True when the numerator is zero.
    pub fn is_zero(&self) -> bool {
        self.num.iter().all(|&b| b == 0.0)
    }

    /// Value at the complex point `p` (`jω` for a continuous model, `e^{jωT}` for a discrete
    /// one), by Horner's rule. At a pole the result is infinite or NaN.
    pub fn eval(&self, p: Complex<f64>) -> Complex<f64> {
        horner(&self.num, p) / horner(&self.den, p)
    }

    /// The monic denominator `[1, a_1 … a_n]` and the numerator divided by the same leading
    /// coefficient and padded with leading zeros to `n + 1` coefficients `[b_0 … b_n]`.
    pub fn monic_padded(&self) -> (Vec<f64>, Vec<f64>) {
        let a0 = self.den[0];
        let n = self.den_degree();
        let mut num = vec![0.0; n + 1 - self.num.len()];
        num.extend(self.num.iter().map(|b| b / a0));
        let den = self.den.iter().map(|a| a / a0).collect();
        (num, den)
    }

    /// The controllable canonical realization (see the module documentation). It has
    /// [`Tf::den_degree`] states, one input and one output.
    pub fn realize(&self) -> StateSpace {
        let (num, den) = self.monic_padded();
        let (a, b, c, d) = canonical_block(&den, &[num]);
        StateSpace { a, b, c, d }
    }
}

fn horner(coeffs: &[f64], p: Complex<f64>) -> Complex<f64> {
    coeffs
        .iter()
        .fold(Complex::new(0.0, 0.0), |acc, &c| acc * p + c)
}

/// Controllable canonical form of `nums[r](p) / den(p)` for every row `r`, one input.
/// `den` is monic with `n + 1` coefficients, every `nums[r]` has `n + 1` coefficients
/// divided by the same leading coefficient.
fn canonical_block(
    den: &[f64],
    nums: &[Vec<f64>],
) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let n = den.len() - 1;
    let mut a = DMatrix::zeros(n, n);
    for i in 0..n {
        a[(0, i)] = -den[i + 1];
        if i > 0 {
            a[(i, i - 1)] = 1.0;
        }
    }
    let mut b = DMatrix::zeros(n, 1);
    if n > 0 {
        b[(0, 0)] = 1.0;
    }
    let mut c = DMatrix::zeros(nums.len(), n);
    let mut d = DMatrix::zeros(nums.len(), 1);
    for (r, num) in nums.iter().enumerate() {
        d[(r, 0)] = num[0];
        for i in 0..n {
            c[(r, i)] = num[i + 1] - num[0] * den[i + 1];
        }
    }
    (a, b, c, d)
}

/// Which of `n` states a search of the graph with the edges `k → l` where `edge(k, l)`
/// reaches from the states where `start(k)`.
fn reached(
    n: usize,
    start: impl Fn(usize) -> bool,
    edge: impl Fn(usize, usize) -> bool,
) -> Vec<bool> {
    let mut reached = vec![false; n];
    let mut stack: Vec<usize> = (0..n).filter(|&k| start(k)).collect();
    while let Some(k) = stack.pop() {
        if reached[k] {
            continue;
        }
        reached[k] = true;
        stack.extend((0..n).filter(|&l| edge(k, l) && !reached[l]));
    }
    reached
}

/// A state-space model `(A, B, C, D)`, continuous or discrete by context (see the module
/// documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpace {
    /// State matrix, `n × n` (`Φ` for a discrete model).
    pub a: DMatrix<f64>,
    /// Input matrix, `n × m` (`Γ` for a discrete model).
    pub b: DMatrix<f64>,
    /// Output matrix, `p × n`.
    pub c: DMatrix<f64>,
    /// Direct feedthrough, `p × m`.
    pub d: DMatrix<f64>,
}

impl StateSpace {
    /// A model whose matrices have consistent dimensions and finite entries.
    pub fn new(
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
    ) -> Result<Self, LtiError> {
        let n = a.nrows();
        check_dims("A", &a, n, n)?;
        check_dims("B", &b, n, b.ncols())?;
        check_dims("C", &c, c.nrows(), n)?;
        check_dims("D", &d, c.nrows(), b.ncols())?;
        Ok(Self { a, b, c, d })
    }

    /// Number of states `n`.
    pub fn n_states(&self) -> usize {
        self.a.nrows()
    }

    /// Number of inputs `m`.
    pub fn n_inputs(&self) -> usize {
        self.b.ncols()
    }

    /// Number of outputs `p`.
    pub fn n_outputs(&self) -> usize {
        self.c.nrows()
    }

    /// The transfer matrix `C (pI − A)^{-1} B + D` at the complex point `p`; an error when
    /// `p` is an eigenvalue of `A`.
    pub fn freq_response(&self, p: Complex<f64>) -> Result<DMatrix<Complex<f64>>, LtiError> {
        let n = self.n_states();
        let to_c = |m: &DMatrix<f64>| m.map(|v| Complex::new(v, 0.0));
        if n == 0 {
            return Ok(to_c(&self.d));
        }
        let mut pa = -to_c(&self.a);
        for i in 0..n {
            pa[(i, i)] += p;
        }
        let x = pa
            .lu()
            .solve(&to_c(&self.b))
            .ok_or_else(|| LtiError::Numerical(format!("pI − A is singular at p = {p}")))?;
        Ok(to_c(&self.c) * x + to_c(&self.d))
    }

    /// The exact zero-order-hold discretization `(Φ, Γ, C, D)` at sample period `t`
    /// (see [`c2d_zoh`]).
    pub fn c2d_zoh(&self, t: f64) -> Result<StateSpace, LtiError> {
        let (phi, gamma) = c2d_zoh(&self.a, &self.b, t)?;
        Ok(StateSpace {
            a: phi,
            b: gamma,
            c: self.c.clone(),
            d: self.d.clone(),
        })
    }

    /// The first `count` Markov parameters `h_0 = D`, `h_k = C A^{k−1} B` (`k ≥ 1`). For a
    /// discrete model they are the impulse response: `y_k = h_k` for `u_0 = 1`, `u_k = 0`
    /// afterwards, from a zero state.
    pub fn markov_parameters(&self, count: usize) -> Vec<DMatrix<f64>> {
        let mut out = Vec::with_capacity(count);
        if count == 0 {
            return out;
        }
        out.push(self.d.clone());
        let mut akb = self.b.clone();
        for _ in 1..count {
            out.push(&self.c * &akb);
            akb = &self.a * akb;
        }
        out
    }

    /// The SISO sub-model from input `input` to output `output` restricted to the states
    /// that the input reaches and that the output sees, judged from the sparsity pattern of
    /// `A`, `B` and `C` (exact zeros). Also returns the indices of the kept states.
    ///
    /// The reduction is exact: the reachable set is closed under the successors in the graph
    /// of `A`, the observable set under the predecessors, so the removed part never affects
    /// the transfer function, and for a continuous model the discretization of the sub-model
    /// is the corresponding sub-block of the discretization of the whole.
    pub fn channel(
        &self,
        output: usize,
        input: usize,
    ) -> Result<(StateSpace, Vec<usize>), LtiError> {
        if output >= self.n_outputs() || input >= self.n_inputs() {
            return Err(LtiError::Channel {
                output,
                input,
                size: (self.n_outputs(), self.n_inputs()),
            });
        }
        let n = self.n_states();
        // Reachable from the input: start where B has a nonzero, follow x_l ← x_k (A[l,k] ≠ 0).
        let reach = reached(
            n,
            |k| self.b[(k, input)] != 0.0,
            |k, l| self.a[(l, k)] != 0.0,
        );
        // Seen by the output: start where C has a nonzero, follow x_k ← x_l (A[k,l] ≠ 0).
        let seen = reached(
            n,
            |k| self.c[(output, k)] != 0.0,
            |k, l| self.a[(k, l)] != 0.0,
        );
        let keep: Vec<usize> = (0..n).filter(|&k| reach[k] && seen[k]).collect();
        let m = keep.len();
        let a = DMatrix::from_fn(m, m, |r, c| self.a[(keep[r], keep[c])]);
        let b = DMatrix::from_fn(m, 1, |r, _| self.b[(keep[r], input)]);
        let c = DMatrix::from_fn(1, m, |_, c| self.c[(output, keep[c])]);
        let d = DMatrix::from_element(1, 1, self.d[(output, input)]);
        Ok((StateSpace { a, b, c, d }, keep))
    }

    /// Numerator and denominator (descending powers, denominator monic, both with `n + 1`
    /// coefficients where `n` is the order of the reduced channel) of the channel
    /// `(output, input)`: see the module documentation for the method. Meant for discrete
    /// models (`A = Φ`, well scaled); for a continuous model with a large `‖A‖` the Markov
    /// parameters grow like `‖A‖^k` and the numerator loses accuracy.
    pub fn channel_tf(
        &self,
        output: usize,
        input: usize,
    ) -> Result<(Vec<f64>, Vec<f64>), LtiError> {
        let (sub, _) = self.channel(output, input)?;
        let den = charpoly(&sub.a)?;
        let n = sub.n_states();
        let h: Vec<f64> = sub
            .markov_parameters(n + 1)
            .iter()
            .map(|m| m[(0, 0)])
            .collect();
        let num = (0..=n)
            .map(|k| (0..=k).map(|i| den[i] * h[k - i]).sum())
            .collect();
        Ok((num, den))
    }
}

/// Exact zero-order-hold discretization of `ẋ = A x + B u` at sample period `t`: the blocks
/// `Φ = e^{At}` and `Γ = ∫_0^t e^{Aτ} dτ B` of the exponential of the augmented matrix
/// `[[A, B], [0, 0]]·t` (see the module documentation).
pub fn c2d_zoh(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    t: f64,
) -> Result<(DMatrix<f64>, DMatrix<f64>), LtiError> {
    if !(t.is_finite() && t > 0.0) {
        return Err(LtiError::SamplePeriod(t));
    }
    let n = a.nrows();
    let m = b.ncols();
    check_dims("A", a, n, n)?;
    check_dims("B", b, n, m)?;
    let size = n + m;
    if size == 0 {
        return Ok((DMatrix::zeros(0, 0), DMatrix::zeros(0, 0)));
    }
    let mut aug = DMatrix::zeros(size, size);
    aug.view_mut((0, 0), (n, n)).copy_from(&(a * t));
    aug.view_mut((0, n), (n, m)).copy_from(&(b * t));
    let e = aug.exp();
    if !e.iter().all(|v| v.is_finite()) {
        return Err(LtiError::Numerical(format!(
            "the matrix exponential overflowed (‖A‖·T = {:.3e})",
            a.norm() * t
        )));
    }
    let phi = e.view((0, 0), (n, n)).into_owned();
    let gamma = e.view((0, n), (n, m)).into_owned();
    Ok((phi, gamma))
}

/// Eigenvalues of a square matrix from its real Schur form (Hessenberg reduction and the
/// implicit double-shift QR iteration). Complex eigenvalues come in conjugate pairs.
pub fn eigenvalues(a: &DMatrix<f64>) -> Result<Vec<Complex<f64>>, LtiError> {
    let n = a.nrows();
    check_dims("the matrix", a, n, n)?;
    if n == 0 {
        return Ok(Vec::new());
    }
    let schur = Schur::try_new(a.clone(), f64::EPSILON, 1000 * n.max(10)).ok_or_else(|| {
        LtiError::Numerical("the Schur (QR) iteration did not converge".to_string())
    })?;
    Ok(schur.complex_eigenvalues().iter().copied().collect())
}

/// The monic polynomial `∏ (p − r_i)`, descending powers, real part of the expansion
/// (exact for roots in conjugate pairs).
pub fn poly_from_roots(roots: &[Complex<f64>]) -> Vec<f64> {
    let mut c = vec![Complex::new(1.0, 0.0)];
    for &r in roots {
        c.push(Complex::new(0.0, 0.0));
        for i in (1..c.len()).rev() {
            let prev = c[i - 1];
            c[i] -= r * prev;
        }
    }
    c.iter().map(|v| v.re).collect()
}

/// The characteristic polynomial `det(pI − A)` (monic, descending powers), expanded from the
/// eigenvalues of `A` ([`eigenvalues`]).
pub fn charpoly(a: &DMatrix<f64>) -> Result<Vec<f64>, LtiError> {
    Ok(poly_from_roots(&eigenvalues(a)?))
}

/// Realizes a matrix of transfer functions, rows = outputs, columns = inputs, `None` = zero
/// entry; the number of inputs is the length of the rows (which must all be equal). See
/// [`realize_tf_matrix_sized`] for the method.
pub fn realize_tf_matrix(rows: &[Vec<Option<Tf>>]) -> Result<StateSpace, LtiError> {
    let inputs = rows.first().map_or(0, |r| r.len());
    realize_tf_matrix_sized(rows, rows.len(), inputs)
}

/// Realizes an `outputs × inputs` matrix of transfer functions (rows = outputs, columns =
/// inputs, `None` = zero entry); rows beyond `rows.len()` are zero, every given row must
/// have `inputs` entries.
///
/// Column by column: when all nonzero entries of a column share the same monic
/// denominator (compared exactly), the column is realized once in controllable canonical
/// form with one row of `C` per output; otherwise every nonzero entry is realized alone.
/// The blocks are stacked block-diagonally in column order (entries in row order inside a
/// column), which fixes the meaning of each state. The realization is exact and may be
/// non-minimal. Zero entries and static gains add no state.
pub fn realize_tf_matrix_sized(
    rows: &[Vec<Option<Tf>>],
    outputs: usize,
    inputs: usize,
) -> Result<StateSpace, LtiError> {
    if rows.len() > outputs {
        return Err(LtiError::Dimension {
            what: "the transfer-function matrix".to_string(),
            expected: (outputs, inputs),
            found: (rows.len(), rows.first().map_or(0, |r| r.len())),
        });
    }
    for (i, r) in rows.iter().enumerate() {
        if r.len() != inputs {
            return Err(LtiError::RaggedRow {
                row: i,
                len: r.len(),
                expected: inputs,
            });
        }
    }
    // One block per (shared) denominator: (input column, monic den, [(output row, num)]).
    type Block = (usize, Vec<f64>, Vec<(usize, Vec<f64>)>);
    let mut blocks: Vec<Block> = Vec::new();
    for j in 0..inputs {
        let entries: Vec<(usize, Vec<f64>, Vec<f64>)> = rows
            .iter()
            .enumerate()
            .filter_map(|(i, r)| r[j].as_ref().filter(|g| !g.is_zero()).map(|g| (i, g)))
            .map(|(i, g)| {
                let (num, den) = g.monic_padded();
                (i, num, den)
            })
            .collect();
        let shared = entries.windows(2).all(|w| w[0].2 == w[1].2);
        if shared && !entries.is_empty() {
            let den = entries[0].2.clone();
            blocks.push((
                j,
                den,
                entries.into_iter().map(|(i, num, _)| (i, num)).collect(),
            ));
        } else {
            for (i, num, den) in entries {
                blocks.push((j, den, vec![(i, num)]));
            }
        }
    }
    let n: usize = blocks.iter().map(|(_, den, _)| den.len() - 1).sum();
    let mut a = DMatrix::zeros(n, n);
    let mut b = DMatrix::zeros(n, inputs);
    let mut c = DMatrix::zeros(outputs, n);
    let mut d = DMatrix::zeros(outputs, inputs);
    let mut at = 0;
    for (j, den, entries) in &blocks {
        let nums: Vec<Vec<f64>> = entries.iter().map(|(_, num)| num.clone()).collect();
        let (ab, bb, cb, db) = canonical_block(den, &nums);
        let k = ab.nrows();
        a.view_mut((at, at), (k, k)).copy_from(&ab);
        b.view_mut((at, *j), (k, 1)).copy_from(&bb);
        for (r, (i, _)) in entries.iter().enumerate() {
            c.view_mut((*i, at), (1, k)).copy_from(&cb.row(r));
            d[(*i, *j)] += db[(r, 0)];
        }
        at += k;
    }
    StateSpace::new(a, b, c, d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
    }

    /// `x` rounded to four significant digits, as text.
    fn four_significant(x: f64) -> String {
        format!("{x:.3e}")
    }

    #[test]
    fn a_tf_is_refused_when_improper_or_its_leading_denominator_is_zero() {
        assert_eq!(
            Tf::new(vec![1.0, 0.0, 0.0], vec![1.0, 1.0]),
            Err(LtiError::Improper {
                num_degree: 2,
                den_degree: 1
            })
        );
        assert_eq!(
            Tf::new(vec![1.0], vec![0.0, 1.0]),
            Err(LtiError::ZeroLeadingDenominator)
        );
        assert_eq!(Tf::new(vec![1.0], vec![]), Err(LtiError::EmptyDenominator));
        assert!(matches!(
            Tf::new(vec![f64::NAN], vec![1.0]),
            Err(LtiError::NonFinite { .. })
        ));
        // Leading zeros of the numerator do not count towards its degree.
        let g = Tf::new(vec![0.0, 0.0, 2.0, 1.0], vec![1.0, 3.0, 2.0]).unwrap();
        assert_eq!(g.num(), &[2.0, 1.0]);
        assert!(Tf::new(vec![], vec![1.0]).unwrap().is_zero());
    }

    #[test]
    fn the_canonical_realization_has_the_frequency_response_of_the_tf() {
        let tfs = [
            Tf::new(vec![2.0, 3.0, 5.0], vec![4.0, 1.0, 7.0, 2.0]).unwrap(),
            Tf::new(vec![3.0, -1.0, 2.0], vec![2.0, 0.5, 8.0]).unwrap(), // feedthrough
            Tf::new(vec![4.0], vec![2.0]).unwrap(),                      // static gain
            Tf::new(vec![0.1871, 0.1831], vec![1.0, -1.569, 0.9391]).unwrap(), // discrete
        ];
        let points = [
            Complex::new(0.0, 0.3),
            Complex::new(0.0, 7.0),
            Complex::new(-0.4, 2.0),
            Complex::new(0.5, 0.5),
            Complex::from_polar(1.0, 0.8),
        ];
        for g in &tfs {
            let ss = g.realize();
            assert_eq!(ss.n_states(), g.den_degree());
            for &p in &points {
                let want = g.eval(p);
                let got = ss.freq_response(p).unwrap()[(0, 0)];
                assert!(
                    (want - got).norm() <= 1e-12 * (1.0 + want.norm()),
                    "{g:?} at {p}"
                );
            }
        }
    }

    #[test]
    fn a_tf_matrix_is_realized_column_wise_sharing_common_denominators() {
        let g1 = Tf::new(vec![1.0, 2.0], vec![1.0, 3.0, 2.0]).unwrap();
        let g2 = Tf::new(vec![5.0], vec![2.0, 6.0, 4.0]).unwrap(); // same monic den as g1
        let g3 = Tf::new(vec![1.0, 0.0], vec![1.0, 1.0]).unwrap(); // feedthrough 1
        let g4 = Tf::new(vec![2.0], vec![1.0, 0.5, 9.0]).unwrap();
        let rows = vec![
            vec![Some(g1.clone()), Some(g3.clone()), None],
            vec![Some(g2.clone()), Some(g4.clone()), None],
            vec![None, None, Some(Tf::new(vec![7.0], vec![1.0]).unwrap())],
        ];
        let ss = realize_tf_matrix(&rows).unwrap();
        // Column 0 shares its denominator (2 states), column 1 does not (1 + 2 states),
        // column 2 is a static gain (no state).
        assert_eq!(ss.n_states(), 5);
        assert_eq!((ss.n_outputs(), ss.n_inputs()), (3, 3));
        for &p in &[
            Complex::new(0.0, 0.7),
            Complex::new(0.2, 3.0),
            Complex::new(-1.5, 0.1),
        ] {
            let h = ss.freq_response(p).unwrap();
            for (i, row) in rows.iter().enumerate() {
                for (j, e) in row.iter().enumerate() {
                    let want = e.as_ref().map_or(Complex::new(0.0, 0.0), |g| g.eval(p));
                    assert!(
                        (h[(i, j)] - want).norm() <= 1e-12 * (1.0 + want.norm()),
                        "({i},{j})"
                    );
                }
            }
        }
        // Missing rows are zero; ragged rows are refused.
        let ss = realize_tf_matrix_sized(&rows[..1], 2, 3).unwrap();
        assert_eq!((ss.n_outputs(), ss.n_states()), (2, 3));
        assert!(ss.c.row(1).iter().all(|&v| v == 0.0));
        let ragged = vec![vec![Some(g1.clone())], vec![Some(g1), None]];
        assert_eq!(
            realize_tf_matrix(&ragged),
            Err(LtiError::RaggedRow {
                row: 1,
                len: 2,
                expected: 1
            })
        );
    }

    #[test]
    fn zoh_discretization_of_a_first_order_plant_is_exact() {
        let (p, t) = (3.0, 0.02);
        let a = DMatrix::from_element(1, 1, -p);
        let b = DMatrix::from_element(1, 1, 1.0);
        let (phi, gamma) = c2d_zoh(&a, &b, t).unwrap();
        assert!(close(phi[(0, 0)], (-p * t).exp(), 1e-15));
        assert!(close(gamma[(0, 0)], (1.0 - (-p * t).exp()) / p, 1e-15));
        assert!(matches!(
            c2d_zoh(&a, &b, 0.0),
            Err(LtiError::SamplePeriod(_))
        ));
        assert!(matches!(
            c2d_zoh(&a, &b, f64::NAN),
            Err(LtiError::SamplePeriod(_))
        ));
    }

    #[test]
    fn discretizing_3_41_at_10_ms_gives_3_42() {
        let w = 20.0 * PI;
        let g = Tf::new(vec![w * w], vec![1.0, 2.0 * PI, w * w]).unwrap();
        let gd = g.realize().c2d_zoh(0.01).unwrap();
        let (num, den) = gd.channel_tf(0, 0).unwrap();
        // (3.42): G_d(z) = (0.1871 z + 0.1831) / (z² − 1.569 z + 0.9391).
        assert!(num[0].abs() < 1e-14, "strictly proper: {num:?}");
        let got: Vec<String> = num[1..]
            .iter()
            .chain(&den)
            .map(|&v| four_significant(v))
            .collect();
        let want: Vec<String> = [0.1871, 0.1831, 1.0, -1.569, 0.9391]
            .iter()
            .map(|&v| four_significant(v))
            .collect();
        assert_eq!(got, want);
    }

    #[test]
    fn markov_parameters_are_the_discrete_impulse_response() {
        let g = Tf::new(vec![0.5, 0.2], vec![1.0, -0.9, 0.2]).unwrap();
        let ss = g.realize();
        let h = ss.markov_parameters(6);
        // Long division of (0.5 z + 0.2) / (z² − 0.9 z + 0.2) in powers of 1/z.
        let mut want = [0.0; 6];
        want[1] = 0.5;
        want[2] = 0.2 + 0.9 * want[1];
        for k in 3..6 {
            want[k] = 0.9 * want[k - 1] - 0.2 * want[k - 2];
        }
        for k in 0..6 {
            assert!(close(h[k][(0, 0)], want[k], 1e-15), "h_{k}");
        }
    }

    #[test]
    fn channel_tf_recovers_the_tf_of_a_realization_including_feedthrough() {
        let g = Tf::new(vec![2.0, -1.0, 0.3, 0.1], vec![2.0, -1.2, 0.4, 0.05]).unwrap();
        let (num, den) = g.realize().channel_tf(0, 0).unwrap();
        let (want_num, want_den) = g.monic_padded();
        for (x, y) in num.iter().zip(&want_num).chain(den.iter().zip(&want_den)) {
            assert!(close(*x, *y, 1e-13), "{num:?} {den:?}");
        }
    }

    #[test]
    fn the_structural_reduction_drops_unreachable_and_unseen_states() {
        let g = Tf::new(vec![1.0], vec![1.0, 2.0]).unwrap();
        let h = Tf::new(vec![1.0], vec![1.0, 5.0, 1.0]).unwrap();
        let rows = vec![vec![Some(g.clone()), Some(h)], vec![Some(g), None]];
        let ss = realize_tf_matrix(&rows).unwrap();
        let (sub, keep) = ss.channel(1, 0).unwrap();
        assert_eq!(keep, vec![0]);
        assert_eq!(sub.n_states(), 1);
        let (num, den) = ss.channel_tf(0, 1).unwrap();
        assert_eq!(den.len(), 3);
        assert!(close(num[2], 1.0, 1e-14) && close(den[1], 5.0, 1e-14));
        assert!(matches!(ss.channel(2, 0), Err(LtiError::Channel { .. })));
    }

    #[test]
    fn poly_from_roots_expands_conjugate_pairs_to_real_coefficients() {
        let r = [
            Complex::new(-1.0, 2.0),
            Complex::new(-1.0, -2.0),
            Complex::new(3.0, 0.0),
        ];
        // (s² + 2 s + 5)(s − 3) = s³ − s² − s − 15
        assert_eq!(poly_from_roots(&r), vec![1.0, -1.0, -1.0, -15.0]);
        assert_eq!(charpoly(&DMatrix::zeros(0, 0)).unwrap(), vec![1.0]);
    }
}
