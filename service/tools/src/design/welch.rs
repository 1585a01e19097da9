//! Frequency-response estimation from measured input/output records: Welch's averaged
//! periodograms, the H1 estimator (multi-input), multiple coherence and pure delays.
//!
//! This is the measured-data branch of the design path of section 3.2 of the
//! dissertation: the dereverberated transfer function is fitted to a frequency response
//! `G_d(e^{jθ})`, which on a real rig comes from data, and (section 3.5) the pure delays
//! of the acoustic experiment (9 and 16 samples at 8 kHz from `u_1` and `u_2` to the
//! microphone) are "characterized and removed" before the fit and added back to the
//! target model afterwards. [`estimate`] gives the raw response and the delays;
//! [`remove_delays`] removes them.
//!
//! ## Welch averaging
//!
//! The records `u_j[n]` (`m` inputs) and `y_o[n]` (`p` outputs), `n = 0 … N−1`, are cut
//! into `K` segments of `L` samples ([`WelchOptions::segment`]) that start every
//! `R = L − round(αL)` samples (overlap `α`, [`WelchOptions::overlap`]),
//! `K = ⌊(N − L)/R⌋ + 1`. In each segment `s` every channel has its mean removed
//! (detrending), is multiplied by the periodic Hann window `w[n] = ½ − ½ cos(2πn/L)` and
//! transformed, `U_j^{(s)}(θ_k) = Σ_n w[n] (u_j[sR+n] − ū_j^{(s)}) e^{−jθ_k n}`,
//! `θ_k = 2πk/L`, `k = 0 … ⌊L/2⌋`. The spectra are averaged over the segments:
//!
//! ```text
//! S_uu(θ_k) = Σ_s U^{(s)} U^{(s)H}    (m × m),   S_yu(θ_k) = Σ_s Y^{(s)} U^{(s)H}    (p × m),
//! S_yy,oo(θ_k) = Σ_s |Y_o^{(s)}|²
//! ```
//!
//! (a common scale factor cancels in everything below). The transform of the periodic
//! Hann window is nonzero only at bins 0 and ±1, so the mean removal changes only bins 0
//! and 1: those two carry a detrending bias and are left out of the coherence summary;
//! do not rely on them.
//!
//! ## H1 estimator and coherence
//!
//! With `y = G u + v` and noise `v` uncorrelated with `u`, `S_yu = G S_uu` in expectation,
//! so per bin
//!
//! ```text
//! Ĝ(θ_k) = S_yu S_uu^{−1}                                   (H1, p × m)
//! γ²_o(θ_k) = (Ĝ S_uu Ĝ^H)_oo / S_yy,oo = (S_yu S_uu^{−1} S_yu^H)_oo / S_yy,oo ∈ [0, 1]
//! ```
//!
//! `γ²_o` is the multiple coherence of output `o` with all inputs: the fraction of its
//! power explained linearly by the measured inputs. It dips where disturbances, noise or
//! unmeasured inputs dominate (the disturbance tones of the acoustic rig, anti-resonances).
//!
//! With several inputs `S_uu` must be invertible, i.e. the inputs must not be coherent
//! with each other. Per bin and input, the coherence of `u_j` with the other inputs is
//! `γ²_{j|rest} = 1 − 1/(S_uu,jj (S_uu^{−1})_jj)`. A bin where it exceeds
//! `0.99` for some input, or where an input has no power (below `10^{−20}` of its largest
//! bin), cannot be resolved: if more than 10 % of the bins are like that, [`estimate`]
//! refuses (correlated or band-limited excitation); otherwise it warns, computes those
//! bins with a slightly regularized `S_uu` and sets their coherence to 0 so that any
//! coherence-weighted use ignores them.
//!
//! ## Accuracy: window bias and leakage
//!
//! For white excitation, `E Ĝ(θ) = Σ_l h[l] ρ(l) e^{−jθl}` with `ρ(l)` the normalized
//! autocorrelation of the window, `1 − ρ(l) ≈ 1.6 (l/L)²` for Hann: lags are weighted
//! down. And since the windowed output of a segment is not exactly the response to the
//! windowed input, every impulse-response tap at lag `l` leaves a part of relative power
//! `≈ (4π²/3)(l/L)² ≈ 13 (l/L)²` unexplained: it acts as extra noise (coherence below 1
//! even without noise) that averaging over segments reduces. Both fall with `L`: choose the
//! segment many times longer than the decay time of the plant (the acoustic rig's lowest
//! mode decays in about 80 samples; the tests use `L = 2048`).
//!
//! A pure delay `d` would add `13 (d/L)²` of such leakage, so the spectra are computed
//! twice: first on the records as given, from which the delays are found (below), then on
//! records aligned by those delays (`u_j` advanced by `d_j` samples against `y`, the first
//! `max d_j` output samples dropped), and the delays are put back exactly, `Ĝ_{oj} ←
//! Ĝ'_{oj} e^{−jθ d_j}`. The response, coherence and segment count returned are those of
//! the aligned pass (the first pass is kept when all delays are 0 or the record is too
//! short to drop `max d_j` samples). A wrong delay estimate only changes the leakage, not
//! the expectation of the estimate.
//!
//! ## Pure delays
//!
//! For each channel `(o, j)` the estimate is extended to the full circle
//! (`Ĝ(θ_{L−k}) = conj Ĝ(θ_k)`) and inverse-transformed to an impulse-response estimate
//! `ĥ[n]`, `n = 0 … L−1`. In expectation `ĥ[n] = h[n] ρ(n)` for a causal plant, with `ρ`
//! the normalized autocorrelation of the window (1 at `n = 0`, falling to 0 at `n = L`),
//! so the last quarter of the buffer (`n ≥ L − ⌊L/4⌋`, lags just below `L` where `ρ ≈ 0`,
//! equivalently the acausal lags `−⌊L/4⌋ … −1`) is pure estimation noise. The rule:
//!
//! ```text
//! σ_tail = RMS of ĥ[n] over the last ⌊L/4⌋ samples
//! i0     = first n < L − ⌊L/4⌋ with |ĥ[n]| > max(6 σ_tail, 10^{−9} max|ĥ|)     (ONSET_FACTOR = 6)
//! d_j    = min over outputs o of (i0(o, j) − 1)   (0 if i0 = 0)
//! ```
//!
//! The `−1`: a sampled zero-order-hold plant has relative degree at least one (`H_0 = 0`,
//! `H_1 = CΓ + D`, with the feedthrough acting one sample late as plant-proxy samples `y_k`
//! before applying `u_k`, see [`super::model`]), and plant-proxy's `input-delays` count
//! the samples beyond that: `H_0 … H_d = 0`, `H_{d+1} ≠ 0` ([`super::model::DiscreteModel::markov`]).
//! A 6σ threshold over the `≈ 3L/4` tested samples gives a false early onset with
//! probability below `10^{−6}` per sample for Gaussian estimation noise; a first Markov
//! parameter smaller than the threshold is missed and the delay comes out late by one or
//! more samples. For the acoustic rig, whose microphone output is displacement-like, the
//! first Markov parameters `H_10` (from `u_1`) and `H_17` (from `u_2`) are small against
//! the resonant peaks of the frequency response, but in the time domain they are 41 % and
//! 56 % of the largest Markov parameter, and with 16 s of 1 V white noise on each
//! loudspeaker their estimates stand about 460σ and 840σ above the floor (see the tests),
//! so the 9- and 16-sample delays of section 3.5 are found exactly. A warning is
//! given when the tail RMS exceeds 5 % of the peak (the response did not decay within a
//! segment, or the data are noisy: use a longer segment or record).
//!
//! [`estimate`] returns the raw H1 response **with** the delays, plus the delays found;
//! [`remove_delays`] multiplies channel `(o, j)` by `e^{jθ d_j}`.
//!
//! Everything here is offline code: it allocates freely.

use super::{C64, Frf};
use nalgebra::DMatrix;
use rustfft::FftPlanner;
use std::f64::consts::PI;

/// Records whose frequency response cannot be estimated, naming the record (`u0`, `y1`)
/// or the option at fault and saying what would do.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WelchError {
    /// No input or no output record.
    #[error(
        "frequency-response estimate needs at least one input and one output record, got \
         {inputs} inputs and {outputs} outputs"
    )]
    NoRecords {
        /// The input records.
        inputs: usize,
        /// The output records.
        outputs: usize,
    },
    /// A sample period that is not positive.
    #[error("sample period {0} s must be finite and positive")]
    SamplePeriod(f64),
    /// Segments shorter than 16 samples.
    #[error("segment length {0} is too short: use at least 16 samples")]
    Segment(usize),
    /// An overlap outside `[0, 1)`.
    #[error("segment overlap {0} must be in [0, 1) (a fraction of the segment; 0.5 is usual)")]
    Overlap(f64),
    /// A coherence threshold outside `[0, 1]`.
    #[error("min_coherence {0} must be in [0, 1]")]
    MinCoherence(f64),
    /// Records of different lengths.
    #[error("records have different lengths: u0 has {samples} samples, {record} has {length}")]
    Lengths {
        /// The samples of `u0`.
        samples: usize,
        /// The record that differs.
        record: String,
        /// Its samples.
        length: usize,
    },
    /// A NaN or infinite sample.
    #[error(
        "{record}[{index}] is {value}: the records must be finite (cut the record or fix the \
         acquisition)"
    )]
    NotFinite {
        /// The record.
        record: String,
        /// The sample.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// Too few samples for the segments.
    #[error(
        "too few samples: {samples}; {inputs} input(s) with segments of {segment} samples and \
         {:.0} % overlap need at least {needed} samples ({segments} segments), and many more \
         for a low-variance estimate",
        overlap * 100.0
    )]
    TooFew {
        /// The samples.
        samples: usize,
        /// The inputs.
        inputs: usize,
        /// The segment length.
        segment: usize,
        /// The overlap, a fraction.
        overlap: f64,
        /// The samples needed.
        needed: usize,
        /// The segments needed.
        segments: usize,
    },
    /// A constant record.
    #[error("{record} is constant (zero variance): {what}")]
    Constant {
        /// The record.
        record: String,
        /// What that means for it.
        what: &'static str,
    },
    /// Too many bins cannot be resolved: the inputs are not independent.
    #[error(
        "{unresolved}H1 = S_yu S_uu⁻¹ needs inputs that are independent of each other and \
         excite every frequency: drive each input with its own independent broadband signal \
         (or estimate one input at a time)"
    )]
    Dependent {
        /// How many bins, and an example with why.
        unresolved: String,
    },
    /// An output that does not respond to the inputs.
    #[error(
        "y{output}: median coherence with the inputs is {median:.3} (below {INCOHERENT}): \
         incoherent data, the output does not respond to the inputs; check the channel \
         selection, wiring and excitation level"
    )]
    Incoherent {
        /// The output.
        output: usize,
        /// Its median coherence.
        median: f64,
    },
}

message_from!(WelchError);

/// Threshold of the delay rule, in RMS values of the impulse-response tail (see the module
/// documentation).
pub const ONSET_FACTOR: f64 = 6.0;

/// Median coherence below which [`estimate`] refuses: the output does not respond to the
/// inputs.
pub const INCOHERENT: f64 = 0.1;

/// Coherence of an input with the other inputs above which a bin cannot be resolved.
pub const INPUT_COHERENCE_LIMIT: f64 = 0.99;

/// Largest share of unresolvable bins (correlated or unexcited inputs) that [`estimate`]
/// accepts with a warning.
const ILL_SHARE: f64 = 0.1;

/// Options of [`estimate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WelchOptions {
    /// Segment length `L`, samples (at least 16). The resolution is `f_s / L`; the impulse
    /// response must decay within about `L/2` samples for the delay rule.
    pub segment: usize,
    /// Overlap of consecutive segments as a fraction of `L`, in `[0, 1)`.
    pub overlap: f64,
    /// Median coherence per output below which a warning is given.
    pub min_coherence: f64,
}

impl Default for WelchOptions {
    /// `L = 1024`, 50 % overlap, warning below a median coherence of 0.8.
    fn default() -> Self {
        Self {
            segment: 1024,
            overlap: 0.5,
            min_coherence: 0.8,
        }
    }
}

/// The result of [`estimate`].
#[derive(Debug, Clone, PartialEq)]
pub struct FrfEstimate {
    /// The H1 estimate on `θ_k = 2πk/L`, `k = 0 … ⌊L/2⌋`, **with** the pure delays (apply
    /// [`remove_delays`] with [`FrfEstimate::delays`] to remove them).
    pub frf: Frf,
    /// `coherence[o][k]`: multiple coherence of output `o` with all inputs at `θ_k`,
    /// in `[0, 1]` (0 at bins that could not be resolved).
    pub coherence: Vec<Vec<f64>>,
    /// Pure delay of each input, samples, by the rule of the module documentation.
    pub delays: Vec<usize>,
    /// Number of segments averaged (in the delay-aligned pass, see the module documentation).
    pub segments: usize,
    /// Conditions the caller should know about (low coherence, few segments, correlated
    /// inputs at some bins, uncertain delays); empty when all is well.
    pub warnings: Vec<String>,
}

/// Estimates the frequency response from inputs `u` (`m` records) to outputs `y` (`p`
/// records), all of the same length, sampled every `ts` seconds (see the module
/// documentation for the method). Errors, each with a message saying what to fix: no
/// channels, records of different lengths, a non-finite sample (channel and index named),
/// a constant input or output, `segment < 16`, overlap outside `[0, 1)`, too few samples
/// (the number needed is given), inputs correlated at more than 10 % of the bins, and a
/// median coherence below [`INCOHERENT`] (the output does not respond to the inputs).
pub fn estimate(
    u: &[&[f64]],
    y: &[&[f64]],
    ts: f64,
    opts: &WelchOptions,
) -> Result<FrfEstimate, WelchError> {
    let (m, p) = (u.len(), y.len());
    if m == 0 || p == 0 {
        return Err(WelchError::NoRecords {
            inputs: m,
            outputs: p,
        });
    }
    if !(ts.is_finite() && ts > 0.0) {
        return Err(WelchError::SamplePeriod(ts));
    }
    let l = opts.segment;
    if l < 16 {
        return Err(WelchError::Segment(l));
    }
    if !(opts.overlap.is_finite() && (0.0..1.0).contains(&opts.overlap)) {
        return Err(WelchError::Overlap(opts.overlap));
    }
    if !(0.0..=1.0).contains(&opts.min_coherence) {
        return Err(WelchError::MinCoherence(opts.min_coherence));
    }
    let named = |is_u: bool, i: usize| {
        if is_u {
            format!("u{i}")
        } else {
            format!("y{i}")
        }
    };
    let records: Vec<(String, &[f64])> = u
        .iter()
        .enumerate()
        .map(|(j, r)| (named(true, j), *r))
        .chain(y.iter().enumerate().map(|(o, r)| (named(false, o), *r)))
        .collect();
    let n = u[0].len();
    for (name, r) in &records {
        if r.len() != n {
            return Err(WelchError::Lengths {
                samples: n,
                record: name.clone(),
                length: r.len(),
            });
        }
    }
    for (name, r) in &records {
        if let Some(i) = r.iter().position(|v| !v.is_finite()) {
            return Err(WelchError::NotFinite {
                record: name.clone(),
                index: i,
                value: r[i],
            });
        }
    }
    let hop = (l - (opts.overlap * l as f64).round() as usize).max(1);
    let min_segments = 2 * m;
    let needed = l + (min_segments - 1) * hop;
    if n < needed {
        return Err(WelchError::TooFew {
            samples: n,
            inputs: m,
            segment: l,
            overlap: opts.overlap,
            needed,
            segments: min_segments,
        });
    }
    for (name, r) in &records {
        let mean = r.iter().sum::<f64>() / n as f64;
        if r.iter().all(|v| *v == mean) || r.iter().all(|v| *v == r[0]) {
            let what = if name.starts_with('u') {
                "it excites nothing"
            } else {
                "it carries no response"
            };
            return Err(WelchError::Constant {
                record: name.clone(),
                what,
            });
        }
    }
    let nb = l / 2 + 1;
    let mut warnings = Vec::new();

    // ---- First pass on the records as they are; delays from its impulse responses.
    let raw: Vec<&[f64]> = u.iter().chain(y.iter()).copied().collect();
    let first = h1_pass(&raw, m, l, hop);
    let theta: Vec<f64> = (0..nb).map(|k| 2.0 * PI * k as f64 / l as f64).collect();
    let mut frf = Frf {
        ts,
        theta,
        n_outputs: p,
        n_inputs: m,
        response: first.response,
    };
    let delays = estimate_delays(&frf, l, &mut warnings);

    // ---- Second pass on delay-aligned records (less leakage), delays put back.
    let dmax = delays.iter().copied().max().unwrap_or(0);
    let Pass {
        coherence,
        ill,
        segments: k_seg,
        ..
    } = if dmax > 0 && n - dmax >= needed {
        let aligned: Vec<&[f64]> = u
            .iter()
            .zip(&delays)
            .map(|(r, &d)| &r[dmax - d..n - d])
            .chain(y.iter().map(|r| &r[dmax..]))
            .collect();
        let second = h1_pass(&aligned, m, l, hop);
        frf.response = second.response.clone();
        for o in 0..p {
            for (j, &d) in delays.iter().enumerate() {
                for (v, &th) in frf.response[o * m + j].iter_mut().zip(&frf.theta) {
                    *v *= C64::from_polar(1.0, -th * d as f64);
                }
            }
        }
        second
    } else {
        Pass {
            response: Vec::new(),
            ..first
        }
    };
    if k_seg < 10 * m {
        warnings.push(format!(
            "only {k_seg} segments averaged for {m} input(s): the estimate is noisy and the \
             coherence biased up by about {:.2}; record longer or use shorter segments",
            m as f64 / k_seg as f64
        ));
    }
    let hz = |k: usize| frf.theta[k] / (2.0 * PI * ts);
    if !ill.is_empty() {
        let (k0, _, why) = &ill[ill.len() / 2];
        let msg = format!(
            "{} of {nb} bins cannot be resolved (e.g. at {:.1} Hz: {why}); ",
            ill.len(),
            hz(*k0)
        );
        if ill.len() as f64 > ILL_SHARE * nb as f64 {
            return Err(WelchError::Dependent { unresolved: msg });
        }
        warnings.push(format!(
            "{msg}they were computed with a regularized S_uu and their coherence set to 0"
        ));
    }

    // ---- Coherence summary (bins 2 … ⌊L/2⌋: bins 0 and 1 carry the detrending bias).
    for (o, c) in coherence.iter().enumerate() {
        let mut v: Vec<f64> = c[2..].to_vec();
        v.sort_by(f64::total_cmp);
        let median = v[v.len() / 2];
        let below = v.iter().filter(|&&g| g < opts.min_coherence).count();
        if median < INCOHERENT {
            return Err(WelchError::Incoherent { output: o, median });
        }
        if median < opts.min_coherence {
            warnings.push(format!(
                "y{o}: median coherence {median:.3} is below {} ({below} of {} bins below): \
                 noise, disturbances, nonlinearity or unmeasured inputs; trust the estimate only \
                 where the coherence is high",
                opts.min_coherence,
                v.len()
            ));
        }
    }

    Ok(FrfEstimate {
        frf,
        coherence,
        delays,
        segments: k_seg,
        warnings,
    })
}

/// One Welch H1 pass over `records` (the `m` inputs, then the outputs), all of the same
/// length: the response (channel-major, bins `0 … ⌊l/2⌋`), the coherence per output, the
/// unresolvable bins `(bin, input, why)` and the number of segments.
fn h1_pass(records: &[&[f64]], m: usize, l: usize, hop: usize) -> Pass {
    let p = records.len() - m;
    let n = records[0].len();
    let k_seg = (n - l) / hop + 1;
    let nb = l / 2 + 1;
    // ---- Averaged spectra.
    let window: Vec<f64> = (0..l)
        .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / l as f64).cos())
        .collect();
    let mut planner = FftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(l);
    let zero = C64::new(0.0, 0.0);
    let mut scratch = vec![zero; fft.get_inplace_scratch_len()];
    let mut bufs = vec![vec![zero; l]; m + p];
    let mut suu = vec![zero; nb * m * m];
    let mut syu = vec![zero; nb * p * m];
    let mut syy = vec![0.0; nb * p];
    for s in 0..k_seg {
        let start = s * hop;
        for (r, buf) in records.iter().zip(bufs.iter_mut()) {
            let seg = &r[start..start + l];
            let mean = seg.iter().sum::<f64>() / l as f64;
            for ((b, &v), &w) in buf.iter_mut().zip(seg).zip(&window) {
                *b = C64::new((v - mean) * w, 0.0);
            }
            fft.process_with_scratch(buf, &mut scratch);
        }
        let (ub, yb) = bufs.split_at(m);
        for k in 0..nb {
            for a in 0..m {
                let ua = ub[a][k];
                for b in 0..m {
                    suu[(k * m + a) * m + b] += ua * ub[b][k].conj();
                }
            }
            for o in 0..p {
                let yo = yb[o][k];
                for j in 0..m {
                    syu[(k * p + o) * m + j] += yo * ub[j][k].conj();
                }
                syy[k * p + o] += yo.norm_sqr();
            }
        }
    }

    // ---- H1 and coherence per bin.
    let mut max_power = vec![0.0f64; m];
    for k in 0..nb {
        for j in 0..m {
            max_power[j] = max_power[j].max(suu[(k * m + j) * m + j].re);
        }
    }
    let mut response = vec![vec![zero; nb]; p * m];
    let mut coherence = vec![vec![0.0; nb]; p];
    // Unresolvable bins: (bin, input, why).
    let mut ill: Vec<(usize, usize, String)> = Vec::new();
    for k in 0..nb {
        let s = DMatrix::from_fn(m, m, |a, b| suu[(k * m + a) * m + b]);
        let mut bad: Option<(usize, String)> = None;
        for j in 0..m {
            if s[(j, j)].re.is_nan() || s[(j, j)].re <= 1e-20 * max_power[j] {
                bad = Some((j, format!("u{j} has no power")));
                break;
            }
        }
        let inv = s.clone().try_inverse();
        if bad.is_none() {
            match &inv {
                None => bad = Some((0, "the input spectra are singular".into())),
                Some(si) => {
                    for j in 0..m {
                        let g = 1.0 - 1.0 / (s[(j, j)].re * si[(j, j)].re);
                        if g.is_nan() || g > INPUT_COHERENCE_LIMIT {
                            bad =
                                Some((j, format!("u{j} is {g:.4} coherent with the other inputs")));
                            break;
                        }
                    }
                }
            }
        }
        let sinv = match (&bad, inv) {
            (None, Some(si)) => si,
            (_, inv) => {
                // Regularized: S + 1e-6 · (mean diagonal) · I.
                let mut r = s.clone();
                let level = (0..m).map(|j| s[(j, j)].re).sum::<f64>() / m as f64;
                let level = if level > 0.0 { level } else { 1.0 };
                for j in 0..m {
                    r[(j, j)] += C64::new(1e-6 * level, 0.0);
                }
                r.try_inverse()
                    .or(inv)
                    .unwrap_or_else(|| DMatrix::zeros(m, m))
            }
        };
        for o in 0..p {
            let mut explained = zero;
            for j in 0..m {
                let mut h = zero;
                for b in 0..m {
                    h += syu[(k * p + o) * m + b] * sinv[(b, j)];
                }
                response[o * m + j][k] = h;
                explained += h * syu[(k * p + o) * m + j].conj();
            }
            let total = syy[k * p + o];
            coherence[o][k] = if bad.is_some() || total <= 0.0 {
                0.0
            } else {
                (explained.re / total).clamp(0.0, 1.0)
            };
        }
        if let Some((j, why)) = bad {
            ill.push((k, j, why));
        }
    }
    Pass {
        response,
        coherence,
        ill,
        segments: k_seg,
    }
}

/// The result of [`h1_pass`].
struct Pass {
    response: Vec<Vec<C64>>,
    coherence: Vec<Vec<f64>>,
    ill: Vec<(usize, usize, String)>,
    segments: usize,
}

/// The onset of an impulse-response estimate by the rule of the module documentation:
/// `Some((i0, σ_tail, peak))`, or `None` when no sample before the tail exceeds the
/// threshold.
fn onset(h: &[f64]) -> Option<(usize, f64, f64)> {
    let l = h.len();
    let tail_start = l - l / 4;
    let tail = &h[tail_start..];
    let sigma = (tail.iter().map(|v| v * v).sum::<f64>() / tail.len() as f64).sqrt();
    let peak = h[..tail_start].iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let threshold = (ONSET_FACTOR * sigma).max(1e-9 * peak);
    h[..tail_start]
        .iter()
        .position(|v| v.abs() > threshold)
        .map(|i0| (i0, sigma, peak))
}

/// A frequency response whose impulse response cannot be taken.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ImpulseError {
    /// Fewer than 3 bins.
    #[error("an impulse response needs at least 3 bins, got {0}")]
    Bins(usize),
    /// Not the bins of a Welch estimate (`L` given).
    #[error("an impulse response needs the bins 2πk/L, k = 0 … L/2 (L = {0}) of a Welch estimate")]
    NotWelch(usize),
}

message_from!(ImpulseError);

/// The impulse response of every channel of an estimate on the bins `θ_k = 2πk/L`,
/// `k = 0 … L/2` (as [`estimate`] returns it, `L` even): the inverse FFT of the response
/// extended to the full circle by `G(e^{−jθ}) = conj G(e^{jθ})`, `L` samples per channel,
/// channel-major. Its first samples estimate the Markov parameters `H_0, H_1, …` (the FIR
/// target model (3.39) from data); the last quarter is estimation noise for a causal plant.
pub fn impulse_response(frf: &Frf) -> Result<Vec<Vec<f64>>, ImpulseError> {
    let nb = frf.theta.len();
    if nb < 3 {
        return Err(ImpulseError::Bins(nb));
    }
    let l = 2 * (nb - 1);
    let uniform = frf
        .theta
        .iter()
        .enumerate()
        .all(|(k, t)| (t - 2.0 * std::f64::consts::PI * k as f64 / l as f64).abs() < 1e-9);
    if !uniform {
        return Err(ImpulseError::NotWelch(l));
    }
    Ok(inverse_fft(frf, l))
}

/// The inverse FFT of length `l` of every channel of `frf` (bins `2πk/l`, `k = 0 … ⌊l/2⌋`),
/// extended to the full circle by conjugate symmetry.
fn inverse_fft(frf: &Frf, l: usize) -> Vec<Vec<f64>> {
    let nb = frf.theta.len();
    let ifft = FftPlanner::<f64>::new().plan_fft_inverse(l);
    let mut buf = vec![C64::new(0.0, 0.0); l];
    frf.response
        .iter()
        .map(|g| {
            for k in 0..l {
                buf[k] = if k < nb { g[k] } else { g[l - k].conj() };
            }
            ifft.process(&mut buf);
            buf.iter().map(|b| b.re / l as f64).collect()
        })
        .collect()
}

/// The impulse-response estimate of every channel of `frf` (bins `2πk/l`, `k = 0 … ⌊l/2⌋`)
/// and the delay of each input; appends warnings.
fn estimate_delays(frf: &Frf, l: usize, warnings: &mut Vec<String>) -> Vec<usize> {
    let (p, m) = (frf.n_outputs, frf.n_inputs);
    let responses = inverse_fft(frf, l);
    let mut delays = vec![0; m];
    for j in 0..m {
        let mut found: Option<usize> = None;
        for o in 0..p {
            let h = &responses[o * m + j];
            match onset(h) {
                None => warnings.push(format!(
                    "y{o}/u{j}: no impulse-response sample stands {ONSET_FACTOR}× above the \
                     noise floor of the tail: channel left out of the delay of u{j}"
                )),
                Some((i0, sigma, peak)) => {
                    if sigma > 0.05 * peak {
                        warnings.push(format!(
                            "y{o}/u{j}: the impulse-response tail is {:.1} % of the peak (the \
                             response does not decay within a segment, or the data are noisy): \
                             the delay may be overestimated; use a longer segment or record",
                            100.0 * sigma / peak
                        ));
                    }
                    if i0 == 0 {
                        warnings.push(format!(
                            "y{o}/u{j}: the response starts at lag 0 (H_0 ≠ 0): the output is \
                             sampled after the input is applied; delay reported as 0"
                        ));
                    }
                    let d = i0.saturating_sub(1);
                    found = Some(found.map_or(d, |f| f.min(d)));
                }
            }
        }
        match found {
            Some(d) => delays[j] = d,
            None => warnings.push(format!("u{j}: no delay found (reported as 0)")),
        }
    }
    delays
}

/// `frf` with the pure delays removed: channel `(o, j)` multiplied by `e^{jθ d_j}`.
///
/// # Panics
///
/// If `delays` does not have one entry per input of `frf`.
pub fn remove_delays(frf: &Frf, delays: &[usize]) -> Frf {
    assert_eq!(
        delays.len(),
        frf.n_inputs,
        "remove_delays: {} delays for {} inputs",
        delays.len(),
        frf.n_inputs
    );
    let mut out = frf.clone();
    for o in 0..frf.n_outputs {
        for (j, &d) in delays.iter().enumerate() {
            for (v, &th) in out.response[o * frf.n_inputs + j]
                .iter_mut()
                .zip(&frf.theta)
            {
                *v *= C64::from_polar(1.0, th * d as f64);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests;
