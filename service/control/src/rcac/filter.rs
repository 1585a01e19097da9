//! The target model `G_f(q)` as a MIMO filter (`l_z × l_u`) applied incrementally to the
//! control inputs and to the RCAC regressor.
//!
//! Every channel `(o, j)` is a strictly proper difference equation in the backward shift,
//!
//! ```text
//! x_k = Σ_{(m, c) ∈ taps} c · s_{k−m} − Σ_{i=1}^{n} a_i x_{k−i},     every lag m ≥ 1,
//! ```
//!
//! - FIR target model (3.39): `taps = {(i, β H_i[o, j]) : H_i[o, j] ≠ 0}`, `n = 0`;
//! - dereverberated target model (3.49) with delay `d`:
//!   `β z^{−d} (b_0 z^n + … + b_n)/(z^n + a_1 z^{n−1} + … + a_n)`, i.e.
//!   `taps = {(d + i, β b_i) : b_i ≠ 0}` and the denominator `a_1 … a_n`.
//!
//! The same channel filters two sequences: the scalar input `u_{j,k}` (giving
//! `u_{f,k} = G_f(q) u_k`, `u_{f,o,k} = Σ_j x^u_{o,j,k}`) and the `N`-vector regressor
//! `φ_k` (giving `ψ_{o,j,k} = G_{f,oj}(q) φ_k`, the block `j` of row `o` of
//! `Φ_{f,k} = G_f(q) Φ_k`, because row `j` of `Φ_k = I_{l_u} ⊗ φ_kᵀ` holds `φ_kᵀ` in block
//! `j`). The inputs are never stored as vectors: `φ_{k−m}` is the window
//! `[u_{k−m−1}; …; u_{k−m−n_c}; y_{k−m−1}; …; y_{k−m−n_c}]` of the histories of `u` and `y`,
//! which are kept newest-first in doubled ring buffers (each sample is written twice, at
//! slot `s` and `s + L`), so every window is two contiguous slices. The outputs are kept
//! for the recursion only (`n` past `ψ` vectors and `n` past scalars per channel).
//!
//! Work per step: `Σ_channels (|taps| + n)(N + 1)` multiply-adds, no allocation, no
//! re-summing of history beyond the filter's own lags.

use crate::ParamError;
use crate::linalg::axpy;
use crate::target::{TargetForm, TargetModel};
use nalgebra::DMatrix;

/// `(lag, coefficient)` pairs of a channel's numerator.
type Taps = Vec<(usize, f64)>;

/// One `(output, input)` channel of `G_f`.
#[derive(Debug, Clone)]
struct Channel {
    /// `(lag, coefficient)`, lags ≥ 1, β included.
    taps: Taps,
    /// `a_1 … a_n`.
    den: Vec<f64>,
    /// Past regressor outputs `ψ_{k−1} … ψ_{k−n}`: slot `(head + i − 1) mod n` holds
    /// `ψ_{k−i}`; `n · N` values.
    psi_ring: Vec<f64>,
    /// Past scalar outputs `x^u_{k−1} … x^u_{k−n}`, same slots.
    u_ring: Vec<f64>,
    head: usize,
}

/// The target model as an incremental MIMO filter of `u_k` and `Φ_k` (module docs).
#[derive(Debug, Clone)]
pub struct TargetFilter {
    lz: usize,
    lu: usize,
    ly: usize,
    nc: usize,
    /// `N = n_c (l_u + l_y)`.
    nphi: usize,
    /// History length `L` in samples (largest lag + `n_c`).
    len: usize,
    /// Slot of the newest stored sample (`u_{k−1}`, `y_{k−1}` during step `k`).
    pos: usize,
    /// `2 L l_u` values.
    u_hist: Vec<f64>,
    /// `2 L l_y` values.
    y_hist: Vec<f64>,
    /// `l_z · l_u` channels, channel `(o, j)` at `o l_u + j`.
    channels: Vec<Channel>,
}

impl TargetFilter {
    /// Checks that `target` can be run as RCAC's filter, without building it.
    ///
    /// # Errors
    ///
    /// The field relative to the target model, as [`TargetModel::validate`] names it:
    /// `"markov"` or `"channel"` with the index of the entry. A feedthrough (`H_0 ≠ 0`, or
    /// a transfer-function channel with delay 0 and a biproper `Ĝ_d`): `z_k` is sampled
    /// before `u_k` is applied, so `G_{zu,d}` is strictly proper and RCAC's update needs
    /// `G_f` strictly proper to be causal. An unstable denominator (a pole on or outside the
    /// unit circle). A Markov parameter of the wrong size, a channel out of range or
    /// improper.
    pub fn validate(target: &TargetModel) -> Result<(), ParamError> {
        channel_filters(target).map(|_| ())
    }

    /// The largest lag of `G_f`'s numerators (1 when `G_f = 0`); the filter keeps this
    /// many samples plus `n_c` ([`TargetFilter::history_len`]).
    ///
    /// # Errors
    ///
    /// Those of [`TargetFilter::validate`].
    pub fn largest_lag(target: &TargetModel) -> Result<usize, ParamError> {
        channel_filters(target).map(|c| largest_lag(&c))
    }

    /// Builds the filter of `target` for `l_y` measurements and controller order `n_c`,
    /// after [`TargetFilter::validate`].
    ///
    /// # Errors
    ///
    /// Those of [`TargetFilter::validate`].
    pub fn new(target: &TargetModel, ly: usize, nc: usize) -> Result<Self, ParamError> {
        let (lz, lu) = (target.outputs, target.inputs);
        let nphi = nc * (lu + ly);
        let chans = channel_filters(target)?;
        let max_lag = largest_lag(&chans);
        let len = max_lag + nc.max(1);
        let channels = chans
            .into_iter()
            .map(|(taps, den)| {
                let n = den.len();
                Channel {
                    taps,
                    psi_ring: vec![0.0; n * nphi],
                    u_ring: vec![0.0; n],
                    den,
                    head: 0,
                }
            })
            .collect();
        Ok(Self {
            lz,
            lu,
            ly,
            nc,
            nphi,
            len,
            pos: 0,
            u_hist: vec![0.0; 2 * len * lu],
            y_hist: vec![0.0; 2 * len * ly],
            channels,
        })
    }

    /// `N = n_c (l_u + l_y)`, the length of `φ_k`.
    pub fn regressor_len(&self) -> usize {
        self.nphi
    }

    /// History length in samples (largest lag of `G_f` plus `n_c`).
    pub fn history_len(&self) -> usize {
        self.len
    }

    /// The `u` and `y` parts of `φ_{k−m}` (`m < L − n_c + 1`), during step `k` (before
    /// [`TargetFilter::push`] of step `k`): `([u_{k−m−1}; …; u_{k−m−n_c}],
    /// [y_{k−m−1}; …; y_{k−m−n_c}])`.
    #[inline]
    pub fn regressor(&self, m: usize) -> (&[f64], &[f64]) {
        let s = self.pos + m;
        let (nc, lu, ly) = (self.nc, self.lu, self.ly);
        let u = self.u_hist.get(s * lu..(s + nc) * lu).unwrap_or(&[]);
        let y = self.y_hist.get(s * ly..(s + nc) * ly).unwrap_or(&[]);
        (u, y)
    }

    /// Computes `Φ_{f,k}` into `phi_f` (`l_z × l_θ` row-major, `l_θ = l_u N`) and
    /// `u_{f,k}` into `u_f` (`l_z`) from the stored past, and advances the recursions.
    /// Call once per step, before [`TargetFilter::push`] of that step.
    pub fn filter(&mut self, phi_f: &mut [f64], u_f: &mut [f64]) {
        let (lu, nc, nphi) = (self.lu, self.nc, self.nphi);
        let ltheta = lu * nphi;
        let nu = nc * lu;
        u_f.fill(0.0);
        for (idx, ch) in self.channels.iter_mut().enumerate() {
            let (o, j) = (idx / lu, idx % lu);
            let start = o * ltheta + j * nphi;
            let Some(out) = phi_f.get_mut(start..start + nphi) else {
                continue;
            };
            out.fill(0.0);
            let mut xu = 0.0;
            for &(lag, c) in &ch.taps {
                let s = self.pos + lag;
                if let (Some(us), Some(ys)) = (
                    self.u_hist.get(s * lu..(s + nc) * lu),
                    self.y_hist.get(s * self.ly..(s + nc) * self.ly),
                ) {
                    let (ou, oy) = out.split_at_mut(nu.min(out.len()));
                    axpy(c, us, ou);
                    axpy(c, ys, oy);
                }
                // u_{j,k−lag} is sample slot pos + lag − 1.
                if let Some(v) = self.u_hist.get((s - 1) * lu + j) {
                    xu += c * v;
                }
            }
            let n = ch.den.len();
            if n > 0 {
                for (i, &a) in ch.den.iter().enumerate() {
                    let slot = (ch.head + i) % n;
                    if let Some(past) = ch.psi_ring.get(slot * nphi..(slot + 1) * nphi) {
                        axpy(-a, past, out);
                    }
                    if let Some(v) = ch.u_ring.get(slot) {
                        xu -= a * v;
                    }
                }
                ch.head = (ch.head + n - 1) % n;
                let slot = ch.head;
                if let Some(dst) = ch.psi_ring.get_mut(slot * nphi..(slot + 1) * nphi) {
                    dst.copy_from_slice(out);
                }
                if let Some(dst) = ch.u_ring.get_mut(slot) {
                    *dst = xu;
                }
            }
            if let Some(d) = u_f.get_mut(o) {
                *d += xu;
            }
        }
    }

    /// Stores the applied `u_k` (`l_u`) and the measurement `y_k` (`l_y`) at the end of
    /// step `k`: they become `u_{k'−1}`, `y_{k'−1}` of the next step.
    pub fn push(&mut self, u: &[f64], y: &[f64]) {
        let (len, lu, ly) = (self.len, self.lu, self.ly);
        self.pos = (self.pos + len - 1) % len;
        for s in [self.pos, self.pos + len] {
            if let Some(d) = self.u_hist.get_mut(s * lu..(s + 1) * lu) {
                for (d, v) in d.iter_mut().zip(u) {
                    *d = *v;
                }
            }
            if let Some(d) = self.y_hist.get_mut(s * ly..(s + 1) * ly) {
                for (d, v) in d.iter_mut().zip(y) {
                    *d = *v;
                }
            }
        }
    }

    /// Replaces the newest stored input (`u_{k−1}` during step `k`) by what the plant
    /// really applied. Call before [`TargetFilter::filter`] of step `k`: the filter reads
    /// `u_{k−1}` first in that call (its lags are ≥ 1), so nothing computed so far used it.
    pub fn correct_last_u(&mut self, u: &[f64]) {
        let (len, lu) = (self.len, self.lu);
        for s in [self.pos, self.pos + len] {
            if let Some(d) = self.u_hist.get_mut(s * lu..(s + 1) * lu) {
                for (d, v) in d.iter_mut().zip(u) {
                    *d = *v;
                }
            }
        }
    }

    /// Zero history and zero filter states (the state after construction).
    pub fn reset(&mut self) {
        self.pos = 0;
        self.u_hist.fill(0.0);
        self.y_hist.fill(0.0);
        for ch in &mut self.channels {
            ch.psi_ring.fill(0.0);
            ch.u_ring.fill(0.0);
            ch.head = 0;
        }
    }

    /// Number of outputs `l_z`.
    pub fn outputs(&self) -> usize {
        self.lz
    }
}

/// Largest root magnitude of `z^n + a_1 z^{n−1} + … + a_n` (companion-matrix eigenvalues;
/// allocates, construction only).
/// Checks the target model as a filter and returns the taps and the denominator of every
/// `(output, input)` channel, at `o l_u + j` (the errors of [`TargetFilter::validate`]).
fn channel_filters(target: &TargetModel) -> Result<Vec<(Taps, Vec<f64>)>, ParamError> {
    let (lz, lu) = (target.outputs, target.inputs);
    let mut chans: Vec<(Taps, Vec<f64>)> = vec![(Vec::new(), Vec::new()); lz * lu];
    let beta = target.beta;
    match &target.form {
        TargetForm::Markov(hs) => {
            for (i, h) in hs.iter().enumerate() {
                if h.nrows() != lz || h.ncols() != lu {
                    return Err(ParamError::at(
                        "markov",
                        i,
                        format!("is {}×{}, expected {lz}×{lu}", h.nrows(), h.ncols()),
                    ));
                }
                for o in 0..lz {
                    for j in 0..lu {
                        let c = h[(o, j)];
                        if c == 0.0 {
                            continue;
                        }
                        if i == 0 {
                            return Err(ParamError::at(
                                "markov",
                                0,
                                format!(
                                    "H_0[{o}][{j}] = {c} is a feedthrough; z_k is sampled \
                                         before u_k is applied, so G_f must be strictly proper \
                                         (H_0 = 0)"
                                ),
                            ));
                        }
                        chans[o * lu + j].0.push((i, beta * c));
                    }
                }
            }
        }
        TargetForm::TransferFunction(list) => {
            for (k, ch) in list.iter().enumerate() {
                if ch.output >= lz || ch.input >= lu || ch.den.is_empty() {
                    return Err(ParamError::at("channel", k, "is out of range"));
                }
                let n = ch.den.len() - 1;
                if ch.num.len() > n + 1 {
                    return Err(ParamError::at("channel", k, "is improper"));
                }
                let pad = n + 1 - ch.num.len();
                let mut taps = Vec::new();
                for (t, &b) in ch.num.iter().enumerate() {
                    let lag = ch.delay + pad + t;
                    if b == 0.0 {
                        continue;
                    }
                    if lag == 0 {
                        return Err(ParamError::at(
                            "channel",
                            k,
                            format!(
                                "(output {}, input {}) has a feedthrough (delay 0 and deg \
                                     num = deg den); z_k is sampled before u_k is applied, so \
                                     G_f must be strictly proper",
                                ch.output, ch.input
                            ),
                        ));
                    }
                    taps.push((lag, beta * b));
                }
                if taps.is_empty() {
                    continue; // a zero channel
                }
                let den: Vec<f64> = ch.den[1..].to_vec();
                if !den.is_empty() {
                    let r = spectral_radius(&den);
                    if r.is_nan() || r >= 1.0 {
                        return Err(ParamError::at(
                            "channel",
                            k,
                            format!(
                                "(output {}, input {}) has a pole of magnitude {r:.6} ≥ 1; \
                                     G_f must be asymptotically stable",
                                ch.output, ch.input
                            ),
                        ));
                    }
                }
                chans[ch.output * lu + ch.input] = (taps, den);
            }
        }
    }
    Ok(chans)
}

/// The largest lag of any channel's numerator (1 when every channel is zero).
fn largest_lag(chans: &[(Taps, Vec<f64>)]) -> usize {
    chans
        .iter()
        .flat_map(|(t, _)| t.iter().map(|(l, _)| *l))
        .max()
        .unwrap_or(1)
}

fn spectral_radius(a: &[f64]) -> f64 {
    let n = a.len();
    let mut c = DMatrix::<f64>::zeros(n, n);
    for (j, v) in a.iter().enumerate() {
        c[(0, j)] = -v;
    }
    for i in 1..n {
        c[(i, i - 1)] = 1.0;
    }
    c.complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}
