//! The value shapes the tables share, and their checks.
//!
//! - a scalar for every channel or one value per channel ([`ScalarOrVec`],
//!   [`per_channel`]): `y-min = -10.0` or `y-min = [-10.0, -5.0]`;
//! - a scalar times the identity or a square matrix ([`ScalarOrMatrix`], [`weight`]):
//!   `rz = 1.0` or `rz = [[1.0, 0.0], [0.0, 2.0]]`;
//! - a matrix written as a list of rows ([`matrix`]);
//! - durations in seconds within bounds ([`seconds`]), counts within bounds ([`count`]),
//!   magnitudes within a bound ([`magnitudes`]), fields not read by a setting
//!   ([`refuse_given`]);
//! - a string field that must be one of a few names ([`one_of`]).
//!
//! Every check names the field it refuses through the `ErrFn` of the file being read.

use super::ConfigError;
use super::ErrFn;
use nalgebra::DMatrix;
use serde::Deserialize;

/// A scalar or one value per channel.
#[derive(Deserialize, Clone)]
#[serde(untagged)]
pub(super) enum ScalarOrVec {
    Scalar(f64),
    Vec(Vec<f64>),
}

/// A scalar (times the identity) or a square matrix.
#[derive(Deserialize)]
#[serde(untagged)]
pub(super) enum ScalarOrMatrix {
    Scalar(f64),
    Matrix(Vec<Vec<f64>>),
}

/// A scalar (for every channel) or `n` values, `default` when absent; refused naming
/// `field` otherwise.
pub(super) fn per_channel(
    v: &Option<ScalarOrVec>,
    n: usize,
    default: f64,
    field: &str,
    err: &ErrFn<'_>,
) -> Result<Vec<f64>, ConfigError> {
    match v {
        None => Ok(vec![default; n]),
        Some(ScalarOrVec::Scalar(x)) => Ok(vec![*x; n]),
        Some(ScalarOrVec::Vec(xs)) if xs.len() == n => Ok(xs.clone()),
        Some(ScalarOrVec::Vec(xs)) => Err(err(
            field,
            format!(
                "has {} values, expected {n} (one per channel) or a scalar",
                xs.len()
            ),
        )),
    }
}

/// A duration in seconds that must be finite, positive (or, with `zero_ok`, ≥ 0) and at
/// most `max` s.
pub(super) fn seconds(
    v: f64,
    zero_ok: bool,
    max: f64,
    field: &str,
    err: &ErrFn<'_>,
) -> Result<f64, ConfigError> {
    let low_ok = if zero_ok { v >= 0.0 } else { v > 0.0 };
    if low_ok && v <= max {
        Ok(v)
    } else {
        let low = if zero_ok { "[0" } else { "(0" };
        Err(err(
            field,
            format!("{v} s is not a duration in {low}, {max}] s"),
        ))
    }
}

/// A count that must lie in `min..=max`.
pub(super) fn count(
    v: u64,
    min: u64,
    max: u64,
    field: &str,
    err: &ErrFn<'_>,
) -> Result<u64, ConfigError> {
    if (min..=max).contains(&v) {
        Ok(v)
    } else if v < min {
        Err(err(field, format!("{v}: must be at least {min}")))
    } else {
        Err(err(field, format!("{v} is above the bound {max}")))
    }
}

/// Refuses the first of the `(given, name)` fields that is given: they are not read
/// `why` (for example `only for update = "rls"`); `table` is the dotted path of their
/// table.
pub(super) fn refuse_given(
    fields: &[(bool, &str)],
    table: &str,
    why: &str,
    err: &ErrFn<'_>,
) -> Result<(), ConfigError> {
    match fields.iter().find(|(given, _)| *given) {
        Some((_, name)) => Err(err(&format!("{table}.{name}"), why.to_string())),
        None => Ok(()),
    }
}

/// Values whose magnitude must not exceed `max` (an initial estimate: beyond it the
/// products of a step overflow).
pub(super) fn magnitudes(
    v: &[f64],
    max: f64,
    field: &str,
    err: &ErrFn<'_>,
) -> Result<(), ConfigError> {
    match v.iter().position(|x| x.abs() > max) {
        Some(i) => Err(err(
            field,
            format!("entry {i} = {} exceeds the bound ±{max}", v[i]),
        )),
        None => Ok(()),
    }
}

/// A matrix from its rows; no rows give `0 × cols_if_empty`. Rows of different lengths
/// are refused, naming the row (`name` is the matrix's name in the message).
pub(super) fn matrix(
    rows: &[Vec<f64>],
    cols_if_empty: usize,
    name: &str,
) -> Result<DMatrix<f64>, String> {
    if rows.is_empty() {
        return Ok(DMatrix::zeros(0, cols_if_empty));
    }
    let n = rows[0].len();
    if let Some((i, r)) = rows.iter().enumerate().find(|(_, r)| r.len() != n) {
        return Err(format!(
            "{name}: row {i} has {} entries, row 0 has {n}",
            r.len()
        ));
    }
    Ok(DMatrix::from_fn(rows.len(), n, |i, j| rows[i][j]))
}

/// `n × n` weight from a scalar (times I) or a matrix; `None` gives `default · I`. Only
/// the shape is checked here; the definiteness is the kernel's to check.
pub(super) fn weight(
    v: &Option<ScalarOrMatrix>,
    n: usize,
    default: f64,
    field: &str,
    err: &ErrFn<'_>,
) -> Result<DMatrix<f64>, ConfigError> {
    match v {
        None => Ok(DMatrix::identity(n, n) * default),
        Some(ScalarOrMatrix::Scalar(x)) => Ok(DMatrix::identity(n, n) * *x),
        Some(ScalarOrMatrix::Matrix(rows)) => {
            let m = matrix(rows, 0, field).map_err(|m| err(field, m))?;
            if m.nrows() != n || m.ncols() != n {
                return Err(err(
                    field,
                    format!("is {}×{}, expected {n}×{n}", m.nrows(), m.ncols()),
                ));
            }
            Ok(m)
        }
    }
}

/// The value named `given` among `options` (`name`, value), `default` when absent;
/// refused naming `field` and the names it may take otherwise.
pub(super) fn one_of<T: Copy>(
    given: Option<&str>,
    default: T,
    options: &[(&str, T)],
    field: &str,
    err: &ErrFn<'_>,
) -> Result<T, ConfigError> {
    let Some(given) = given else {
        return Ok(default);
    };
    options
        .iter()
        .find(|(name, _)| *name == given)
        .map(|(_, v)| *v)
        .ok_or_else(|| {
            let names: Vec<&str> = options.iter().map(|(n, _)| *n).collect();
            err(
                field,
                format!("'{given}' is not one of {}", names.join(", ")),
            )
        })
}

/// The row-major entries of `a`.
pub(super) fn row_major(a: &DMatrix<f64>) -> Vec<f64> {
    let mut v = Vec::with_capacity(a.len());
    for i in 0..a.nrows() {
        for j in 0..a.ncols() {
            v.push(a[(i, j)]);
        }
    }
    v
}
