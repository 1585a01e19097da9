//! Which shard this process is: `--shard I/N`, or a cluster job array's environment.
//!
//! Shard `I` of `N` (`0 ≤ I < N`) runs the study's runs whose number `g` has
//! `g mod N = I` (see the [module documentation](super)). Where the index and count come
//! from, first match wins:
//!
//! 1. `--shard I/N`, or `--shard none` for the whole study whatever the environment says;
//! 2. a Slurm job array: `SLURM_ARRAY_TASK_ID`, `SLURM_ARRAY_TASK_MIN`,
//!    `SLURM_ARRAY_TASK_STEP` (1 when unset) and `SLURM_ARRAY_TASK_COUNT`; the shard is
//!    `I = (ID − MIN) / STEP` of `N = COUNT`, so `--array=1-8`, `--array=0-30:2` and
//!    `--array=5-40:5` all give shards `0 … N−1`. A task whose ID is not `MIN + k·STEP`
//!    with `k < COUNT` (a list such as `--array=1,4,9`) is refused: give `--shard`;
//! 3. a Kubernetes Indexed Job: `JOB_COMPLETION_INDEX` (0-based) is `I`; Kubernetes does
//!    not pass the Job's `completions`, so `N` is `STUDY_SHARD_COUNT`, which the Job's
//!    manifest sets to its `completions` (`docs/studies.md`).
//!
//! Without any of these the study runs whole.

use std::fmt;

/// Shard `index` of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Slice {
    /// This shard, `0 … count−1`.
    pub index: usize,
    /// How many shards the study is split into.
    pub count: usize,
}

impl fmt::Display for Slice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Why the shard could not be told.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SliceError {
    /// `--shard` that is not `I/N` with `0 ≤ I < N`, or `none`.
    #[error("--shard {0}: expected I/N with 0 ≤ I < N (e.g. 3/8), or none")]
    Option(String),
    /// An environment variable that is not a number.
    #[error("{name}={value}: not a whole number")]
    NotANumber {
        /// The variable.
        name: &'static str,
        /// Its value.
        value: String,
    },
    /// A Slurm task that is not `MIN + k·STEP` with `k < COUNT`.
    #[error(
        "SLURM_ARRAY_TASK_ID={id} is not SLURM_ARRAY_TASK_MIN={min} + k × SLURM_ARRAY_TASK_STEP={step} with k < SLURM_ARRAY_TASK_COUNT={count}: an array given as a list cannot be numbered 0…N−1; give --shard I/N"
    )]
    SlurmTask {
        /// `SLURM_ARRAY_TASK_ID`.
        id: usize,
        /// `SLURM_ARRAY_TASK_MIN`.
        min: usize,
        /// `SLURM_ARRAY_TASK_STEP`.
        step: usize,
        /// `SLURM_ARRAY_TASK_COUNT`.
        count: usize,
    },
    /// A Slurm array variable the index needs is missing.
    #[error(
        "SLURM_ARRAY_TASK_ID is set but {0} is not: cannot number the shards; give --shard I/N"
    )]
    SlurmMissing(&'static str),
    /// A Kubernetes index without `STUDY_SHARD_COUNT`.
    #[error(
        "JOB_COMPLETION_INDEX={0} gives this shard's index but not the count: set STUDY_SHARD_COUNT to the Job's completions (docs/studies.md), or give --shard I/N"
    )]
    KubernetesCount(usize),
    /// An index at or beyond the count.
    #[error("{source_name}: shard {index} of {count} (the index is 0-based, below the count)")]
    OutOfRange {
        /// Where the numbers came from.
        source_name: &'static str,
        /// The index.
        index: usize,
        /// The count.
        count: usize,
    },
}

impl Slice {
    /// Parses `--shard`: `I/N`, or `none` (`None`: the whole study).
    pub fn parse(text: &str) -> Result<Option<Slice>, SliceError> {
        let t = text.trim();
        if t.eq_ignore_ascii_case("none") {
            return Ok(None);
        }
        let bad = || SliceError::Option(text.to_string());
        let (i, n) = t.split_once('/').ok_or_else(bad)?;
        let index: usize = i.trim().parse().map_err(|_| bad())?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Some(Slice { index, count }))
    }

    /// The shard that `--shard` (if given) or the environment `var` names; `None`: the
    /// whole study.
    pub fn resolve(
        option: Option<&str>,
        var: impl Fn(&str) -> Option<String>,
    ) -> Result<Option<Slice>, SliceError> {
        if let Some(text) = option {
            return Slice::parse(text);
        }
        let number = |name: &'static str| -> Result<Option<usize>, SliceError> {
            match var(name) {
                None => Ok(None),
                Some(v) if v.trim().is_empty() => Ok(None),
                Some(value) => value
                    .trim()
                    .parse()
                    .map(Some)
                    .map_err(|_| SliceError::NotANumber { name, value }),
            }
        };
        if let Some(id) = number("SLURM_ARRAY_TASK_ID")? {
            let min = number("SLURM_ARRAY_TASK_MIN")?
                .ok_or(SliceError::SlurmMissing("SLURM_ARRAY_TASK_MIN"))?;
            let count = number("SLURM_ARRAY_TASK_COUNT")?
                .ok_or(SliceError::SlurmMissing("SLURM_ARRAY_TASK_COUNT"))?;
            let step = number("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1).max(1);
            let task = SliceError::SlurmTask {
                id,
                min,
                step,
                count,
            };
            let offset = id.checked_sub(min).ok_or_else(|| task.clone())?;
            if offset % step != 0 || offset / step >= count {
                return Err(task);
            }
            return Ok(Some(Slice {
                index: offset / step,
                count,
            }));
        }
        if let Some(index) = number("JOB_COMPLETION_INDEX")? {
            let count = number("STUDY_SHARD_COUNT")?.ok_or(SliceError::KubernetesCount(index))?;
            if index >= count {
                return Err(SliceError::OutOfRange {
                    source_name: "JOB_COMPLETION_INDEX and STUDY_SHARD_COUNT",
                    index,
                    count,
                });
            }
            return Ok(Some(Slice { index, count }));
        }
        Ok(None)
    }

    /// True when run number `g` is this shard's.
    pub fn owns(&self, g: usize) -> bool {
        g % self.count == self.index
    }

    /// The shard's folder name: `I-of-N`.
    pub fn folder_name(&self) -> String {
        format!("{}-of-{}", self.index, self.count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let m: HashMap<String, String> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |k| m.get(k).cloned()
    }

    #[test]
    fn the_option_is_i_of_n_or_none_and_wins_over_the_environment() {
        let slurm = env(&[
            ("SLURM_ARRAY_TASK_ID", "3"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ]);
        assert_eq!(
            Slice::resolve(Some("1/3"), &slurm).unwrap(),
            Some(Slice { index: 1, count: 3 })
        );
        assert_eq!(Slice::resolve(Some("none"), &slurm).unwrap(), None);
        assert_eq!(
            Slice::resolve(None, &slurm).unwrap(),
            Some(Slice { index: 3, count: 4 })
        );
        for bad in ["3/3", "1/0", "1", "a/b", "-1/2", "1/2/3"] {
            let e = Slice::parse(bad).unwrap_err().to_string();
            assert!(e.starts_with(&format!("--shard {bad}:")), "{e}");
        }
        assert_eq!(Slice::resolve(None, env(&[])).unwrap(), None);
    }

    #[test]
    fn slurm_stepped_and_offset_arrays_number_the_shards_from_zero() {
        // --array=5-40:5: IDs 5, 10, …, 40 (8 tasks).
        let ids: Vec<usize> = (5..=40).step_by(5).collect();
        let got: Vec<usize> = ids
            .iter()
            .map(|id| {
                let id = id.to_string();
                Slice::resolve(
                    None,
                    env(&[
                        ("SLURM_ARRAY_TASK_ID", id.as_str()),
                        ("SLURM_ARRAY_TASK_MIN", "5"),
                        ("SLURM_ARRAY_TASK_STEP", "5"),
                        ("SLURM_ARRAY_TASK_COUNT", "8"),
                    ]),
                )
                .unwrap()
                .unwrap()
                .index
            })
            .collect();
        assert_eq!(got, (0..8).collect::<Vec<_>>());
        // --array=1,4,9: not a range; refused with the variables named.
        let e = Slice::resolve(
            None,
            env(&[
                ("SLURM_ARRAY_TASK_ID", "4"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_COUNT", "3"),
            ]),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("SLURM_ARRAY_TASK_ID=4") && e.contains("--shard"),
            "{e}"
        );
        let e = Slice::resolve(None, env(&[("SLURM_ARRAY_TASK_ID", "4")])).unwrap_err();
        assert_eq!(e, SliceError::SlurmMissing("SLURM_ARRAY_TASK_MIN"));
    }

    #[test]
    fn a_kubernetes_index_needs_the_count_beside_it() {
        assert_eq!(
            Slice::resolve(
                None,
                env(&[("JOB_COMPLETION_INDEX", "0"), ("STUDY_SHARD_COUNT", "5")])
            )
            .unwrap(),
            Some(Slice { index: 0, count: 5 })
        );
        let e = Slice::resolve(None, env(&[("JOB_COMPLETION_INDEX", "2")]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("STUDY_SHARD_COUNT"), "{e}");
        let e = Slice::resolve(
            None,
            env(&[("JOB_COMPLETION_INDEX", "5"), ("STUDY_SHARD_COUNT", "5")]),
        )
        .unwrap_err();
        assert!(matches!(e, SliceError::OutOfRange { index: 5, .. }));
        let e = Slice::resolve(None, env(&[("JOB_COMPLETION_INDEX", "x")])).unwrap_err();
        assert!(e.to_string().starts_with("JOB_COMPLETION_INDEX=x"));
    }

    #[test]
    fn round_robin_gives_every_run_to_exactly_one_shard() {
        for count in 1..6 {
            for g in 0..50 {
                let owners = (0..count)
                    .filter(|&index| Slice { index, count }.owns(g))
                    .count();
                assert_eq!(owners, 1);
            }
        }
    }
}
