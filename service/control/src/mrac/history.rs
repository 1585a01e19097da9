//! A fixed-length history of a scalar signal, newest first, and FIR sums over it.
//!
//! `History::get(i)` is the value pushed `i` pushes ago (`get(0)` the newest), 0 before
//! anything was pushed there (the signals are zero before the first sample, the initial
//! condition of every transfer function of chapter 4). Pushing shifts in place; nothing
//! allocates after [`History::new`].

/// The last `len` values of a signal, newest first.
#[derive(Debug, Clone)]
pub(crate) struct History {
    buf: Vec<f64>,
}

impl History {
    /// A history of `len` zeros (at least one slot).
    pub(crate) fn new(len: usize) -> Self {
        Self {
            buf: vec![0.0; len.max(1)],
        }
    }

    /// Shifts `v` in as the newest value.
    #[inline]
    pub(crate) fn push(&mut self, v: f64) {
        let n = self.buf.len();
        self.buf.copy_within(0..n - 1, 1);
        if let Some(d) = self.buf.first_mut() {
            *d = v;
        }
    }

    /// The value pushed `i` pushes ago; 0 beyond the stored length.
    #[inline]
    pub(crate) fn get(&self, i: usize) -> f64 {
        self.buf.get(i).copied().unwrap_or(0.0)
    }

    /// Replaces the newest value (the input the plant really applied).
    pub(crate) fn set_newest(&mut self, v: f64) {
        if let Some(d) = self.buf.first_mut() {
            *d = v;
        }
    }

    /// All zeros again.
    pub(crate) fn clear(&mut self) {
        self.buf.fill(0.0);
    }

    /// `Σ_l c_l x_{k−lag−l}` with `get(lag + l)` standing for `x_{k−lag−l}`: the FIR
    /// filter `C(q⁻¹)` applied at lag `lag`.
    #[inline]
    pub(crate) fn fir(&self, c: &[f64], lag: usize) -> f64 {
        let mut s = 0.0;
        for (l, cl) in c.iter().enumerate() {
            s += cl * self.get(lag + l);
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn newest_first_with_zeros_before_the_start() {
        let mut h = History::new(3);
        h.push(1.0);
        h.push(2.0);
        assert_eq!(
            (h.get(0), h.get(1), h.get(2), h.get(7)),
            (2.0, 1.0, 0.0, 0.0)
        );
        h.push(3.0);
        h.push(4.0);
        assert_eq!((h.get(0), h.get(2)), (4.0, 2.0));
        // (1 − 0.5 q⁻¹) x at lag 1: x_{k−1} − 0.5 x_{k−2} = 3 − 1.
        assert_eq!(h.fir(&[1.0, -0.5], 1), 2.0);
        h.clear();
        assert_eq!(h.get(0), 0.0);
    }
}
