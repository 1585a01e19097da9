//! The model-following error norm (4.85) of a controller that follows a reference model
//! (APPC and RC-MRAC, chapter 4): `‖e‖ = sqrt(Σ_{i = first}^{last} e_i²)` over the configured
//! window of sample indices (`service.report.error-window`; the chapter's is 101–200), and
//! over the whole run, from the controller's `e_k = y_k − y_{m,k}`
//! ([`control::Controller::model_following_error`]). Accumulating is a few additions per
//! sample: no allocation.

use serde::Serialize;

/// The sums behind the report.
#[derive(Debug, Clone, Copy, Default)]
pub struct ModelFollowing {
    window: Option<(u64, u64)>,
    sum_sq: f64,
    samples: u64,
    window_sum_sq: f64,
    window_samples: u64,
}

/// `‖e‖` (4.85) of a run, in the run report.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ModelFollowingReport {
    /// `sqrt(Σ e_i²)` over every sample the controller stepped.
    pub norm: f64,
    /// The samples in that sum.
    pub samples: u64,
    /// The window `[first, last]` of sample indices, when configured.
    pub window: Option<(u64, u64)>,
    /// `sqrt(Σ e_i²)` over the window (4.85), when configured.
    pub window_norm: Option<f64>,
    /// The samples of the window that were stepped (fewer than its length when some were
    /// lost or the run ended before it did).
    pub window_samples: u64,
}

impl ModelFollowing {
    /// Sums over the whole run and over `window` (sample indices, inclusive) when given.
    pub const fn new(window: Option<(u64, u64)>) -> Self {
        Self {
            window,
            sum_sq: 0.0,
            samples: 0,
            window_sum_sq: 0.0,
            window_samples: 0,
        }
    }

    /// Adds `e` of sample `seq`.
    #[inline]
    pub fn record(&mut self, seq: u64, e: f64) {
        self.sum_sq += e * e;
        self.samples += 1;
        if let Some((first, last)) = self.window
            && (first..=last).contains(&seq)
        {
            self.window_sum_sq += e * e;
            self.window_samples += 1;
        }
    }

    /// The norms, when the controller reported an error at least once.
    pub fn report(&self) -> Option<ModelFollowingReport> {
        (self.samples > 0).then(|| ModelFollowingReport {
            norm: self.sum_sq.sqrt(),
            samples: self.samples,
            window: self.window,
            window_norm: self.window.map(|_| self.window_sum_sq.sqrt()),
            window_samples: self.window_samples,
        })
    }
}

impl ModelFollowingReport {
    /// The report's line.
    pub fn line(&self) -> String {
        let window = match (self.window, self.window_norm) {
            (Some((a, b)), Some(n)) => format!(
                "{n:.4e} over samples {a}–{b} ({} of them stepped), ",
                self.window_samples
            ),
            _ => String::new(),
        };
        format!(
            "model-following error ‖e‖ (4.85): {window}{:.4e} over the run ({} samples)\n",
            self.norm, self.samples
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_norm_sums_the_window_and_the_whole_run() {
        let mut m = ModelFollowing::new(Some((2, 3)));
        for (k, e) in [3.0, 4.0, 1.0, 2.0, 10.0].into_iter().enumerate() {
            m.record(k as u64, e);
        }
        let r = m.report().unwrap();
        assert_eq!(r.norm, (9.0f64 + 16.0 + 1.0 + 4.0 + 100.0).sqrt());
        assert_eq!(r.window_norm, Some(5.0f64.sqrt()));
        assert_eq!((r.samples, r.window_samples), (5, 2));
        assert!(r.line().contains("over samples 2–3"), "{}", r.line());
        assert_eq!(ModelFollowing::new(None).report(), None);
    }
}
