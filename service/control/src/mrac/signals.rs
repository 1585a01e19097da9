//! The sample handling both controllers share: the histories of `y`, `u`, `r`, `r_f` and
//! `e`, the reference model, and what happens on a bad or missing sample.
//!
//! At sample `k` ([`Signals::take_in`]) `y_k` and `r_k` are pushed, `r_{f,k} = F(q⁻¹) r_k`
//! (4.70) (`F = 1` for APPC), `y_{m,k}` (4.4) and `e_k = y_k − y_{m,k}` are formed; the
//! input history holds `u_{k−1}, u_{k−2}, …` until the controller pushes `u_k`
//! ([`Signals::push_u`]). All signals are zero before the first sample.
//!
//! - A non-finite `y_k` or `r_k` (or a command so large that `y_{m,k}` or `e_k` is not
//!   finite) makes the sample bad: the last finite `y`, `r` (and `e`) are pushed in its
//!   place, so that the histories stay aligned with the plant's samples, and the
//!   estimator's update is suspended until the substituted values have left every window
//!   the regression reads (`settle` samples).
//! - [`StepInput::u_applied`](crate::StepInput::u_applied), when finite, replaces the
//!   stored `u_{k−1}` before anything reads it.
//! - `m` lost samples ([`StepInput::lost`](crate::StepInput::lost)) are bridged by
//!   `min(m, settle)` entries with the held `y`, `r` and `u` (the plant held its input),
//!   and the update is suspended for `settle` samples.

use super::history::History;
use super::reference::ReferenceModel;
use crate::StepInput;

/// Why the estimator's update is suspended (the last event that suspended it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Suspension {
    /// Lost samples were bridged with held values.
    Gap,
    /// A non-finite sample was replaced by the held one.
    BadSample,
}

/// The histories and holds of a model-reference controller (module docs).
#[derive(Debug, Clone)]
pub(crate) struct Signals {
    /// `y.get(i) = y_{k−i}` after [`Signals::take_in`].
    pub(crate) y: History,
    /// `u.get(i) = u_{k−1−i}` during sample `k` (until [`Signals::push_u`]).
    pub(crate) u: History,
    /// `r.get(i) = r_{k−i}`.
    r: History,
    /// `rf.get(i) = r_{f,k−i}`, `r_f = F(q⁻¹) r` (4.70).
    pub(crate) rf: History,
    /// `e.get(i) = e_{k−i}`.
    pub(crate) e: History,
    f: Vec<f64>,
    reference: ReferenceModel,
    y_hold: f64,
    r_hold: f64,
    /// `y_{m,k}` (NaN on a bad sample).
    pub(crate) y_m: f64,
    /// `e_k` (NaN on a bad sample).
    pub(crate) e_k: f64,
    /// `r_k` as used (the held value on a bad sample).
    pub(crate) r_k: f64,
    k: u64,
    update_from: u64,
    /// What set `update_from` last.
    pub(crate) suspension: Suspension,
    settle: u64,
    gaps: u64,
}

impl Signals {
    /// Histories of `len` samples for `y`, `u`, `r`, `r_f` and `e`, the reference model
    /// `N_m/D_m`, the prefilter `F`; updates are suspended for `len` samples after a bad
    /// or missing sample.
    pub(crate) fn new(len: usize, n_m: &[f64], d_m: &[f64], f: &[f64]) -> Self {
        Self {
            y: History::new(len),
            u: History::new(len),
            r: History::new(len.max(f.len())),
            rf: History::new(len),
            e: History::new(len),
            f: f.to_vec(),
            reference: ReferenceModel::new(n_m, d_m),
            y_hold: 0.0,
            r_hold: 0.0,
            y_m: 0.0,
            e_k: 0.0,
            r_k: 0.0,
            k: 0,
            update_from: 0,
            suspension: Suspension::Gap,
            settle: len as u64,
            gaps: 0,
        }
    }

    /// `u_{k−j}` during sample `k`, `j ≥ 1`.
    #[inline]
    pub(crate) fn u_lag(&self, j: usize) -> f64 {
        self.u.get(j.wrapping_sub(1))
    }

    /// Applies `u_applied` and bridges lost samples (module docs).
    pub(crate) fn absorb(&mut self, input: &StepInput<'_>) {
        if let Some(&ua) = input.u_applied.and_then(|v| v.first())
            && ua.is_finite()
        {
            self.u.set_newest(ua);
        }
        if input.lost > 0 {
            let held_u = self.u.get(0);
            for _ in 0..input.lost.min(self.settle) {
                self.push_data(self.y_hold, self.r_hold, true);
                self.u.push(held_u);
            }
            self.k = self.k.saturating_add(input.lost);
            self.update_from = self.k.saturating_add(self.settle);
            self.suspension = Suspension::Gap;
            self.gaps += 1;
        }
    }

    /// Pushes `y`, `r`, `r_f`, `y_m`, `e`; returns false (after pushing held values) when
    /// something is not finite. `held`: the values are already substitutes.
    fn push_data(&mut self, y: f64, r: f64, held: bool) -> bool {
        let ok = y.is_finite() && r.is_finite();
        let (y, r) = if ok {
            (y, r)
        } else {
            (self.y_hold, self.r_hold)
        };
        self.r.push(r);
        let y_m = self.reference.step(r);
        let e = y - y_m;
        let rf = self.r.fir(&self.f, 0);
        let fine = ok && e.is_finite() && rf.is_finite();
        self.y.push(y);
        self.rf.push(if rf.is_finite() { rf } else { 0.0 });
        self.e.push(if e.is_finite() { e } else { self.e.get(0) });
        if fine && !held {
            self.y_hold = y;
            self.r_hold = r;
        }
        self.y_m = if fine { y_m } else { f64::NAN };
        self.e_k = if fine { e } else { f64::NAN };
        self.r_k = r;
        fine
    }

    /// Takes in `y_k` and `r_k` (module docs); returns whether the sample is good. A bad
    /// sample suspends the update for `settle` samples.
    pub(crate) fn take_in(&mut self, input: &StepInput<'_>) -> bool {
        let y = input.y.first().copied().unwrap_or(f64::NAN);
        let r = input.r.first().copied().unwrap_or(f64::NAN);
        let ok = self.push_data(y, r, false);
        if !ok {
            self.update_from = self.k.saturating_add(self.settle + 1);
            self.suspension = Suspension::BadSample;
        }
        ok
    }

    /// Whether the regression of this sample may be used (no substituted value in its
    /// windows).
    pub(crate) fn learn(&self) -> bool {
        self.k >= self.update_from
    }

    /// Pushes the applied `u_k` and ends sample `k`.
    pub(crate) fn push_u(&mut self, u: f64) {
        self.u.push(u);
        self.k = self.k.saturating_add(1);
    }

    /// `C(q⁻¹) r_k = Σ_l c_l r_{k−l}` (`H r_k` of (4.43)).
    pub(crate) fn r_fir(&self, c: &[f64]) -> f64 {
        self.r.fir(c, 0)
    }

    /// The last applied input `u_{k−1}`.
    pub(crate) fn u_last(&self) -> f64 {
        self.u.get(0)
    }

    /// Gaps bridged so far.
    pub(crate) fn gaps(&self) -> u64 {
        self.gaps
    }

    /// Forgets the data: zero histories, the reference model at rest, the counter at 0.
    pub(crate) fn clear(&mut self) {
        self.y.clear();
        self.u.clear();
        self.r.clear();
        self.rf.clear();
        self.e.clear();
        self.reference.reset();
        self.y_hold = 0.0;
        self.r_hold = 0.0;
        self.y_m = 0.0;
        self.e_k = 0.0;
        self.r_k = 0.0;
        self.k = 0;
        self.update_from = 0;
    }
}
