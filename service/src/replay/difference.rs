//! The first field in which two actuations differ, bit for bit.

use ipc_types::Actuation;
use std::fmt;

/// Where a replayed actuation first differs from the logged one.
#[derive(Debug, Clone, PartialEq)]
pub struct Difference {
    /// The field (`status`, `u[1]`, `plan[3][0]`, …).
    pub field: String,
    /// Its logged value.
    pub logged: String,
    /// Its replayed value.
    pub replayed: String,
}

impl fmt::Display for Difference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "field {}: logged {}, replayed {}",
            self.field, self.logged, self.replayed
        )
    }
}

/// An `f64` with its bits, so that values that print alike still show how they differ.
fn show(v: f64) -> String {
    format!("{v:?} (0x{:016x})", v.to_bits())
}

/// The first field in which `replayed` differs from `logged` over the first `n_u` inputs and
/// the plan rows of the logged plan length; `None` when they are equal bit for bit. The
/// publication time and the compute time are not compared: they are clock readings.
pub fn first_difference(
    logged: &Actuation,
    replayed: &Actuation,
    n_u: usize,
) -> Option<Difference> {
    let int = |field: &str, a: u64, b: u64| {
        (a != b).then(|| Difference {
            field: field.to_string(),
            logged: a.to_string(),
            replayed: b.to_string(),
        })
    };
    let header = int("seq", logged.seq, replayed.seq)
        .or_else(|| int("reply_to", logged.reply_to, replayed.reply_to))
        .or_else(|| int("t_sample_ns", logged.t_sample_ns, replayed.t_sample_ns))
        .or_else(|| int("status", logged.status.into(), replayed.status.into()))
        .or_else(|| int("timing", logged.timing.into(), replayed.timing.into()))
        .or_else(|| {
            int(
                "contract_version",
                logged.contract_version.into(),
                replayed.contract_version.into(),
            )
        })
        .or_else(|| int("plan_len", logged.plan_len.into(), replayed.plan_len.into()));
    if header.is_some() {
        return header;
    }
    if logged.counts != replayed.counts {
        return Some(Difference {
            field: "counts".into(),
            logged: format!("{:?}", logged.counts),
            replayed: format!("{:?}", replayed.counts),
        });
    }
    let float = |field: String, a: f64, b: f64| {
        (a.to_bits() != b.to_bits()).then(|| Difference {
            field,
            logged: show(a),
            replayed: show(b),
        })
    };
    for i in 0..n_u {
        if let Some(d) = float(format!("u[{i}]"), logged.u[i], replayed.u[i]) {
            return Some(d);
        }
    }
    let rows = logged.plan_len as usize;
    for (j, (a, b)) in logged
        .plan
        .iter()
        .zip(&replayed.plan)
        .take(rows)
        .enumerate()
    {
        for i in 0..n_u {
            if let Some(d) = float(format!("plan[{j}][{i}]"), a[i], b[i]) {
                return Some(d);
            }
        }
    }
    None
}
