//! What a controller learned, apart from the data it learned it from.
//!
//! An adaptive controller carries two kinds of state. What it **learned** is the estimate
//! of its adaptive law: for RCAC the controller coefficients `θ_k` and, with RLS, the
//! covariance `P_k` of (2.13)–(2.14); for PCAC the identified model's coefficients and
//! covariance of (2.30)–(2.32). Its **data history** is the recent signals that the next
//! step reads: the regressor `φ_k` (2.15), the filtered signals of (3.51)–(3.63), the held
//! input, the forgetting rule's windows of prior errors (5.1)–(5.7).
//!
//! The history belongs to one data stream. When a new one begins (a restarted or replaced
//! plant process: a new plant session) the history is forgotten and what was learned is
//! kept ([`Controller::restart_data`](crate::Controller::restart_data)). What was learned
//! is also what a checkpoint holds: the service copies it from the real-time loop
//! ([`Controller::learned`](crate::Controller::learned), named blocks of fixed lengths,
//! without allocating) and a later run starts from it
//! ([`Controller::restore_learned`](crate::Controller::restore_learned), which checks the
//! values before it takes them).
//!
//! The RLS covariance is kept in the blocks exactly as the estimator stores it, so that a
//! restored estimator continues bit for bit: for [`Rls`](crate::rls::Rls) the row-packed
//! upper triangle `Q`, the deferred update `W` and `β` with `P_k = β Q − W Wᵀ`, and
//! `tr P_k`.

use nalgebra::DMatrix;

/// Named blocks of learned values `(name, values)`, in the controller's order.
pub type Blocks = Vec<(String, Vec<f64>)>;

/// The blocks of a checkpoint, by name, as read from its file.
#[derive(Debug, Clone, Copy)]
pub struct Learned<'a> {
    blocks: &'a [(String, Vec<f64>)],
}

impl<'a> Learned<'a> {
    /// The blocks `(name, values)`.
    pub fn new(blocks: &'a [(String, Vec<f64>)]) -> Self {
        Self { blocks }
    }

    /// True when there are no blocks.
    pub fn is_empty(&self) -> bool {
        self.blocks.is_empty()
    }

    /// The block `name`, which must hold `len` finite values.
    ///
    /// # Errors
    ///
    /// A missing block, a wrong length or a non-finite value, naming the block.
    pub fn block(&self, name: &str, len: usize) -> Result<&'a [f64], String> {
        let (_, values) = self
            .blocks
            .iter()
            .find(|(n, _)| n == name)
            .ok_or_else(|| format!("block '{name}' is missing"))?;
        if values.len() != len {
            return Err(format!(
                "block '{name}' has {} values, this controller needs {len}",
                values.len()
            ));
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(format!("block '{name}': value {i} is not finite"));
        }
        Ok(values)
    }

    /// The single value of block `name`.
    ///
    /// # Errors
    ///
    /// As [`Learned::block`].
    pub fn scalar(&self, name: &str) -> Result<f64, String> {
        Ok(self.block(name, 1)?[0])
    }
}

/// The symmetric `n × n` matrix whose upper triangle is row-packed in `packed` (row `i`
/// holds `n − i` entries, diagonal first).
pub fn unpack_symmetric(packed: &[f64], n: usize) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(n, n);
    let mut off = 0;
    for i in 0..n {
        for (t, &v) in packed[off..off + n - i].iter().enumerate() {
            m[(i, i + t)] = v;
            m[(i + t, i)] = v;
        }
        off += n - i;
    }
    m
}

/// Checks that a restored covariance is positive definite (it has a Cholesky factor) and
/// that its trace is positive and at most `trace_limit`, the guard of (2.13)–(2.14).
///
/// # Errors
///
/// Says which condition failed.
pub fn check_covariance(p: &DMatrix<f64>, trace: f64, trace_limit: f64) -> Result<(), String> {
    if !(trace > 0.0 && trace <= trace_limit) {
        return Err(format!(
            "tr P = {trace:e} is outside (0, {trace_limit:e}], the estimator's guard"
        ));
    }
    if p.clone().cholesky().is_none() {
        return Err("the covariance P is not positive definite".into());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_block_is_found_by_name_and_checked() {
        let blocks = vec![
            ("theta".to_string(), vec![1.0, 2.0]),
            ("bad".to_string(), vec![1.0, f64::NAN]),
        ];
        let l = Learned::new(&blocks);
        assert_eq!(l.block("theta", 2).unwrap(), &[1.0, 2.0]);
        assert!(l.block("theta", 3).unwrap_err().contains("has 2 values"));
        assert!(l.block("P", 1).unwrap_err().contains("'P' is missing"));
        assert!(l.block("bad", 2).unwrap_err().contains("value 1"));
    }

    #[test]
    fn unpacking_and_the_covariance_check() {
        // [[2, 1], [1, 2]] packed: 2, 1, 2.
        let m = unpack_symmetric(&[2.0, 1.0, 2.0], 2);
        assert_eq!(m[(1, 0)], 1.0);
        assert!(check_covariance(&m, 4.0, 10.0).is_ok());
        assert!(
            check_covariance(&m, 4.0, 3.0)
                .unwrap_err()
                .contains("guard")
        );
        let indefinite = unpack_symmetric(&[1.0, 2.0, 1.0], 2);
        assert!(
            check_covariance(&indefinite, 2.0, 10.0)
                .unwrap_err()
                .contains("not positive definite")
        );
    }
}
