//! The `O(n² p)` work of [`Rls::update`](super::Rls::update): one fused sweep over the
//! row-packed upper triangle of `P`, and the `O(n p)` diagonal of the next `P`.
//!
//! The sweep of step `k` applies the rank-p update of step `k − 1`, which was deferred,
//!
//! ```text
//! P_k = β_{k−1} P_{k−1} − W_{k−1} W_{k−1}ᵀ          ((2.13)–(2.14), see the parent module)
//! ```
//!
//! to each stored entry, stores it, and feeds the new value straight into
//! `G = P_k φ_kᵀ` (n×p): every stored `P_ij` (`j ≥ i`) is read once, written once, and
//! contributes `P_ij φ_l[j]` to `G[i, l]` (a dot product along row `i`) and, for `j > i`,
//! `P_ij φ_l[i]` to `G[j, l]` (an axpy into column `l` of `G`). One read and one write of
//! `P` per step instead of two reads and a write.
//!
//! Entry `(i, j)` is always computed as `x = β P_ij` (the multiplication skipped when
//! `β = 1`, which is exact), then `x = x − W_jl W_il` rounded once (fused) or twice (not
//! fused) for `l = 0, 1, …, p−1`, in that order. [`next_diag`] and
//! [`Rls::covariance`](super::Rls::covariance) use the same expression, so the
//! diagonal checked at step `k − 1` is bit-for-bit the one the sweep stores at step `k`.
//!
//! Forms, chosen once per estimator by [`Level::detect`]:
//! - [`Level::Avx2Fma`]: explicit AVX2/FMA intrinsics for `p ≤ 4` (two packed rows per
//!   pass, so each vector of `W`, `φ` and `G` loaded serves both rows), the portable code
//!   compiled with AVX2+FMA (fused `x − a b`) for larger `p`;
//! - [`Level::Portable`]: plain loops for the baseline target (unfused products).

use super::{axpy, dot, madd};

/// Which compiled form of the kernels an estimator uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(super) enum Level {
    /// Baseline x86-64 / other targets: no FMA, plain vectorizable loops.
    Portable,
    /// AVX2 and FMA available (checked at run time).
    Avx2Fma,
}

impl Level {
    /// The best form this CPU supports.
    pub(super) fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return Level::Avx2Fma;
        }
        Level::Portable
    }

    /// Whether `x − a b` is fused (one rounding) in this form.
    pub(super) fn fma(self) -> bool {
        self == Level::Avx2Fma
    }
}

/// The pending update `P ← β P − W Wᵀ` of the previous step: `W` (`n × p`, column `l`
/// at `[l n .. (l+1) n]`) and `β`, for `n` parameters and `p` outputs.
#[derive(Clone, Copy)]
pub(super) struct Pending<'a> {
    /// `W`.
    pub w: &'a [f64],
    /// `β`.
    pub beta: f64,
    /// Parameters.
    pub n: usize,
    /// Outputs.
    pub p: usize,
}

/// Applies the pending update to the packed upper triangle `pk` of `P` (`n(n+1)/2`) and
/// computes `G = P φᵀ` (`n × p`) with the new `P` for the regressor `φ` (`p × n`; column
/// `l` of `φ`ᵀ and `G` at `[l n .. (l+1) n]`). Returns whether every new entry of `P` is
/// finite.
pub(super) fn fused_pass(
    level: Level,
    pk: &mut [f64],
    pending: Pending<'_>,
    phi: &[f64],
    g: &mut [f64],
) -> bool {
    let Pending { w, n, p, .. } = pending;
    assert!(pk.len() == n * (n + 1) / 2 && w.len() == n * p && phi.len() == n * p);
    assert!(g.len() == n * p);
    match level {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Avx2Fma` is only produced by `detect` after checking AVX2 and FMA.
        Level::Avx2Fma => unsafe { x86::fused_pass(pk, pending, phi, g) },
        _ => fused_portable::<false>(pk, pending, phi, g),
    }
}

/// The diagonal of the pending update's `β P − W Wᵀ` (not stored) for the packed
/// triangle `pk` of `P`: `(trace, min, all finite)`, each entry computed exactly as
/// [`fused_pass`] will compute it.
pub(super) fn next_diag(level: Level, pk: &[f64], pending: Pending<'_>) -> (f64, f64, bool) {
    match level {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as in `fused_pass`.
        Level::Avx2Fma => unsafe { x86::next_diag(pk, pending) },
        _ => next_diag_impl::<false>(pk, pending),
    }
}

/// One stored entry of `β P − W Wᵀ`: `x = β P_ij`, then `x = x − W_jl W_il` for each `l`.
#[inline(always)]
pub(super) fn entry<const FMA: bool>(
    beta: f64,
    pij: f64,
    w: &[f64],
    n: usize,
    p: usize,
    i: usize,
    j: usize,
) -> f64 {
    let mut x = if beta == 1.0 { pij } else { beta * pij };
    for l in 0..p {
        x = madd::<FMA>(-w[l * n + j], w[l * n + i], x);
    }
    x
}

#[inline(always)]
fn next_diag_impl<const FMA: bool>(pk: &[f64], pending: Pending<'_>) -> (f64, f64, bool) {
    let Pending { w, beta, n, p } = pending;
    let (mut trace, mut min, mut finite) = (0.0, f64::INFINITY, true);
    let mut off = 0;
    for i in 0..n {
        let d = entry::<FMA>(beta, pk[off], w, n, p, i, i);
        off += n - i;
        trace += d;
        min = min.min(d);
        finite &= d.is_finite();
    }
    (trace, min, finite)
}

/// [`fused_pass`] for any `p`: per packed row, the update in `p` vectorizable passes
/// (the row stays in L1), then `p` dot products and axpys with the new row.
#[inline(always)]
pub(super) fn fused_portable<const FMA: bool>(
    pk: &mut [f64],
    pending: Pending<'_>,
    phi: &[f64],
    g: &mut [f64],
) -> bool {
    let Pending { w, beta, n, p } = pending;
    let g = &mut g[..n * p];
    g.fill(0.0);
    let mut finite = true;
    let mut off = 0;
    for i in 0..n {
        let len = n - i;
        let row = &mut pk[off..off + len];
        off += len;
        if beta != 1.0 {
            for v in row.iter_mut() {
                *v *= beta;
            }
        }
        for wl in w.chunks_exact(n).take(p) {
            let wi = wl[i];
            for (x, &wj) in row.iter_mut().zip(&wl[i..]) {
                *x = madd::<FMA>(-wj, wi, *x);
            }
        }
        // Branch-free, vectorizable finiteness check (NaN or ±∞ anywhere ⇒ false).
        finite &= row.iter().fold(true, |ok, x| ok & x.is_finite());
        for l in 0..p {
            let f = &phi[l * n..(l + 1) * n];
            let gl = &mut g[l * n..(l + 1) * n];
            let s = dot(&row[1..], &f[i + 1..]);
            gl[i] += row[0] * f[i] + s;
            axpy(f[i], &row[1..], &mut gl[i + 1..]);
        }
    }
    finite
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::Pending;
    use core::arch::x86_64::*;

    /// [`super::fused_pass`] with AVX2+FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn fused_pass(
        pk: &mut [f64],
        pending: Pending<'_>,
        phi: &[f64],
        g: &mut [f64],
    ) -> bool {
        let s = pending.beta != 1.0;
        match (pending.p, s) {
            (1, false) => fused_fixed::<1, false>(pk, pending, phi, g),
            (1, true) => fused_fixed::<1, true>(pk, pending, phi, g),
            (2, false) => fused_fixed::<2, false>(pk, pending, phi, g),
            (2, true) => fused_fixed::<2, true>(pk, pending, phi, g),
            (3, false) => fused_fixed::<3, false>(pk, pending, phi, g),
            (3, true) => fused_fixed::<3, true>(pk, pending, phi, g),
            (4, false) => fused_fixed::<4, false>(pk, pending, phi, g),
            (4, true) => fused_fixed::<4, true>(pk, pending, phi, g),
            _ => super::fused_portable::<true>(pk, pending, phi, g),
        }
    }

    /// [`super::next_diag`] with FMA.
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn next_diag(pk: &[f64], pending: Pending<'_>) -> (f64, f64, bool) {
        super::next_diag_impl::<true>(pk, pending)
    }

    /// The new value of one entry, scalar: the same operations as the vector loop.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn upd<const P: usize, const SCALE: bool>(
        beta: f64,
        x: f64,
        wj: &[f64; P],
        wi: &[f64; P],
    ) -> f64 {
        let mut x = if SCALE { beta * x } else { x };
        for l in 0..P {
            x = (-wj[l]).mul_add(wi[l], x);
        }
        x
    }

    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn hsum(v: __m256d) -> f64 {
        let lo = _mm256_castpd256_pd128(v);
        let hi = _mm256_extractf128_pd::<1>(v);
        let s = _mm_add_pd(lo, hi);
        _mm_cvtsd_f64(_mm_add_sd(s, _mm_unpackhi_pd(s, s)))
    }

    /// The fused sweep for a compile-time `p = P`, two packed rows `(i, i+1)` per pass;
    /// `SCALE` is `β ≠ 1` (with `β = 1` the multiplication is skipped, which is exact).
    ///
    /// Columns `j ≥ i + 2` are shared by both rows and run four at a time: load `P_ij`,
    /// `P_{i+1,j}`; update them with the vectors `W_l[j..]` (shared) and the broadcast
    /// scalars `W_l[i]`, `W_l[i+1]`; store; accumulate `Σ_j P_ij φ_l[j]` in registers and
    /// add `φ_l[i] P_ij + φ_l[i+1] P_{i+1,j}` into `G_l[j]`. The three head entries
    /// `P_ii`, `P_{i,i+1}`, `P_{i+1,i+1}` and the tail columns (`< 4`) are done in scalar
    /// code with the same operations. Non-finite values are detected branch-free: `x − x`
    /// is `0` for finite `x` and NaN otherwise, summed into a check register.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn fused_fixed<const P: usize, const SCALE: bool>(
        pk: &mut [f64],
        pending: Pending<'_>,
        phi: &[f64],
        g: &mut [f64],
    ) -> bool {
        let Pending { w, beta, n, .. } = pending;
        assert!(pk.len() == n * (n + 1) / 2 && w.len() == P * n);
        assert!(phi.len() == P * n && g.len() == P * n);
        g.fill(0.0);
        let pkp = pk.as_mut_ptr();
        let wp: [*const f64; P] = std::array::from_fn(|l| w[l * n..].as_ptr());
        let fp: [*const f64; P] = std::array::from_fn(|l| phi[l * n..].as_ptr());
        let gbase = g.as_mut_ptr();
        // SAFETY (for every raw access below): rows `i, i+1 < n`, packed offsets within
        // `n(n+1)/2` (row `i` has `n − i` entries starting at `off`), column indices
        // `< n` within each length-`n` column of `w`, `phi`, `g` (lengths asserted above).
        let gp: [*mut f64; P] = std::array::from_fn(|l| unsafe { gbase.add(l * n) });
        let vbeta = _mm256_set1_pd(beta);
        let mut chk = _mm256_setzero_pd();
        let mut ok = true;
        let mut off = 0usize;
        let mut i = 0usize;
        unsafe {
            while i + 1 < n {
                let len_a = n - i;
                let ra = pkp.add(off);
                let rb = pkp.add(off + len_a);
                off += 2 * len_a - 1;
                let wa: [f64; P] = std::array::from_fn(|l| *wp[l].add(i));
                let wb: [f64; P] = std::array::from_fn(|l| *wp[l].add(i + 1));
                let fa: [f64; P] = std::array::from_fn(|l| *fp[l].add(i));
                let fb: [f64; P] = std::array::from_fn(|l| *fp[l].add(i + 1));
                // Head: P_ii, P_{i,i+1}, P_{i+1,i+1}.
                let a0 = upd::<P, SCALE>(beta, *ra, &wa, &wa);
                let a1 = upd::<P, SCALE>(beta, *ra.add(1), &wb, &wa);
                let b1 = upd::<P, SCALE>(beta, *rb, &wb, &wb);
                *ra = a0;
                *ra.add(1) = a1;
                *rb = b1;
                ok &= a0.is_finite() & a1.is_finite() & b1.is_finite();
                // Shared columns j = i+2 .. n.
                let m = n - i - 2;
                let pa = ra.add(2);
                let pb = rb.add(1);
                let col = i + 2;
                let vwa: [__m256d; P] = std::array::from_fn(|l| _mm256_set1_pd(wa[l]));
                let vwb: [__m256d; P] = std::array::from_fn(|l| _mm256_set1_pd(wb[l]));
                let vfa: [__m256d; P] = std::array::from_fn(|l| _mm256_set1_pd(fa[l]));
                let vfb: [__m256d; P] = std::array::from_fn(|l| _mm256_set1_pd(fb[l]));
                let mut acc_a = [_mm256_setzero_pd(); P];
                let mut acc_b = [_mm256_setzero_pd(); P];
                let body = m - m % 4;
                let mut t = 0;
                while t < body {
                    let mut xa = _mm256_loadu_pd(pa.add(t));
                    let mut xb = _mm256_loadu_pd(pb.add(t));
                    if SCALE {
                        xa = _mm256_mul_pd(vbeta, xa);
                        xb = _mm256_mul_pd(vbeta, xb);
                    }
                    for l in 0..P {
                        let wj = _mm256_loadu_pd(wp[l].add(col + t));
                        xa = _mm256_fnmadd_pd(wj, vwa[l], xa);
                        xb = _mm256_fnmadd_pd(wj, vwb[l], xb);
                    }
                    _mm256_storeu_pd(pa.add(t), xa);
                    _mm256_storeu_pd(pb.add(t), xb);
                    chk = _mm256_add_pd(chk, _mm256_sub_pd(xa, xa));
                    chk = _mm256_add_pd(chk, _mm256_sub_pd(xb, xb));
                    for l in 0..P {
                        let f = _mm256_loadu_pd(fp[l].add(col + t));
                        acc_a[l] = _mm256_fmadd_pd(xa, f, acc_a[l]);
                        acc_b[l] = _mm256_fmadd_pd(xb, f, acc_b[l]);
                        let gj = gp[l].add(col + t);
                        let v = _mm256_fmadd_pd(vfa[l], xa, _mm256_loadu_pd(gj));
                        _mm256_storeu_pd(gj, _mm256_fmadd_pd(vfb[l], xb, v));
                    }
                    t += 4;
                }
                let mut sa: [f64; P] = std::array::from_fn(|l| hsum(acc_a[l]));
                let mut sb: [f64; P] = std::array::from_fn(|l| hsum(acc_b[l]));
                while t < m {
                    let wj: [f64; P] = std::array::from_fn(|l| *wp[l].add(col + t));
                    let xa = upd::<P, SCALE>(beta, *pa.add(t), &wj, &wa);
                    let xb = upd::<P, SCALE>(beta, *pb.add(t), &wj, &wb);
                    *pa.add(t) = xa;
                    *pb.add(t) = xb;
                    ok &= xa.is_finite() & xb.is_finite();
                    for l in 0..P {
                        let f = *fp[l].add(col + t);
                        sa[l] = xa.mul_add(f, sa[l]);
                        sb[l] = xb.mul_add(f, sb[l]);
                        let gj = gp[l].add(col + t);
                        *gj = fb[l].mul_add(xb, fa[l].mul_add(xa, *gj));
                    }
                    t += 1;
                }
                for l in 0..P {
                    let gi = gp[l].add(i);
                    *gi += a0 * fa[l] + a1 * fb[l] + sa[l];
                    let gi1 = gp[l].add(i + 1);
                    *gi1 += a1 * fa[l] + b1 * fb[l] + sb[l];
                }
                i += 2;
            }
            if i < n {
                // Last row alone: only its diagonal entry.
                let r = pkp.add(off);
                let wi: [f64; P] = std::array::from_fn(|l| *wp[l].add(i));
                let d = upd::<P, SCALE>(beta, *r, &wi, &wi);
                *r = d;
                ok &= d.is_finite();
                for l in 0..P {
                    *gp[l].add(i) += d * *fp[l].add(i);
                }
            }
        }
        let nan = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_UNORD_Q>(chk, chk));
        ok && nan == 0
    }
}
