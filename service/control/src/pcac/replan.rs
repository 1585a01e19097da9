//! Multi-rate re-planning for PCAC's ahead form: the plan the plant follows between
//! solves, and which part of the next solve each sample period does.
//!
//! # The problem solved every `N` samples
//!
//! With [`PcacParams::replan_every`](super::PcacParams::replan_every) `= N` the MPC
//! (2.43)–(2.51) is solved at every `N`-th sample `k` only, and its work is spread over
//! the `N` periods that follow, so that no period carries a whole solve. The inputs of
//! those periods are already decided when the solve starts: `u_k` is being applied, and
//! `u_{k+1}, …, u_{k+N−1}` are the rows of the plan in force (the previous solve's). The
//! solve at `k` therefore plans from the state those inputs lead to,
//!
//! ```text
//! x_{1|k} = Â_k x̂_k + B̂_k u_k,   x_{j+1|k} = Â_k x_{j|k} + B̂_k u_{k+j},   j < N      (2.36)
//! ```
//!
//! ([`HorizonPrediction::compute_committed`](crate::bocf::HorizonPrediction::compute_committed)),
//! with the last committed input `u_{k+N−1}` as the move reference of (2.47), and its
//! solution `U = [u_{N|k}; …; u_{N+ℓ−1|k}]` becomes the plan for the samples
//! `k+N, …, k+N+ℓ−1`; the next solve replaces it at `k+2N`, so `ℓ ≥ N` rows always
//! cover the time until then. With `N = 1` this is the dissertation's next-step timing
//! (§2.3.2.2): `x_{1|k}`, the move reference `u_k` and the first move applied at `k + 1`.
//!
//! The computation delay is thus accounted for exactly by the model: the cost of a
//! larger `N` is that a disturbance or model change is answered `N − 1` samples later
//! and the plan runs open loop for `N` samples, not that the QP plans from a stale state.
//!
//! # The work of one solve, in three units
//!
//! 1. **predict**: the committed inputs, `x̂_k`, `x_{N|k}`, the Markov parameters and the
//!    free response ((2.36)–(2.46)), and the command `𝓡`;
//! 2. **build**: the condensed QP's Hessian from the Markov parameters
//!    ([`Condenser::build_quadratic`](crate::mpc::condense::Condenser::build_quadratic)),
//!    or, when it is chosen and its minimizer meets every constraint, the unconstrained
//!    fast path's solution instead ([`crate::mpc::fast_path`], on the realization kept
//!    by the prediction), which leaves the solve unit nothing to build or solve;
//! 3. **solve**: the rest of the QP from the free response
//!    ([`Condenser::build_linear`](crate::mpc::condense::Condenser::build_linear)), then
//!    the warm-started QP
//!    ([`DenseQpSolver::solve`](crate::mpc::qp::DenseQpSolver::solve)), the plan rows
//!    clipped into the input bounds (2.50), or the fallback.
//!
//! Position `i = 0 … N−1` of a cycle (the sample `k + i`) runs unit `j` when
//! `max(0, j − (3 − min(N, 3))) = i`: with `N ≥ 3` one unit per period (predict, build,
//! solve in the first three), with `N = 2` predict and build in the first and the solve
//! in the second, with `N = 1` all three. Identification runs at every sample, as
//! always. The new plan takes over at the last position (`i = N − 1`), so the input sent
//! ahead for `k + N` is its first row.
//!
//! With `N ≥ 4` the solve may go on over the periods `3 … N−1` as well
//! ([`PcacParams::qp_changes_per_period`](super::PcacParams::qp_changes_per_period)
//! `= B > 0`): the third period completes the QP and begins the solve
//! ([`DenseQpSolver::start`](crate::mpc::qp::DenseQpSolver::start): its checks and the
//! copy of `H`); each later period factors one panel of `H = L Lᵀ` (of a bounded number
//! of multiply–adds), and once `L` is complete makes at most `B` active-set changes (the
//! start point's rounds, then constraint additions)
//! ([`DenseQpSolver::proceed`](crate::mpc::qp::DenseQpSolver::proceed)); the last
//! period does what remains (up to the iteration cap). The QP's work is thus cut
//! into shares no larger than a panel, or `B` changes (and one round or addition begun),
//! except in the last period, and its result is the one solve's, bit for bit; the new
//! plan takes over at the last position, as with the solve in one period. `N` must leave
//! periods for the panels (about ten at `ℓ m = 128`) and the changes, or the last period
//! carries them.
//!
//! # Keeping the Hessian
//!
//! The Hessian `H` of (2.48) depends on the identified model only through its Markov
//! parameters, which change slowly once the model has converged; the free response, the
//! gradient `f` and the right-hand sides change with every sample. With
//! [`PcacParams::hessian_every`](super::PcacParams::hessian_every) `= M > 1` only every
//! `M`-th cycle builds `H` (and the QP factors it); it is
//! [`PcacParams::hessian_cycle`](super::PcacParams::hessian_cycle) `= N_H ≥ N` samples
//! long, room for the build and the factorization's panels, and runs the three units
//! above. The cycles in between are `N` samples long and run two units, **predict** in
//! the first period and **solve** in the second (`N = 1`: both in one), with the shares of
//! the QP after it as above: their `f` and right-hand sides come from their own
//! prediction and the kept `G_s` (the Markov parameters of the build), and the QP starts
//! from the kept factorization ([`crate::mpc::qp`], "Keeping the factorization"). The
//! plan of a kept cycle is therefore the MPC of a model whose Markov parameters are up to
//! `M` cycles old and whose free response is current; with a model that does not change
//! it is the plan of a build at every cycle, bit for bit (test
//! `a_hessian_kept_between_builds_gives_the_inputs_of_a_build_at_every_cycle`). A reset,
//! an identification reset by the RLS guard, a dropped build cycle or a failed build
//! make the next cycle build.
//!
//! A cycle is abandoned when its data no longer hold: a sample taken in without
//! adaptation (the loop caught up, or the safe state), or samples lost before the one at
//! hand (the plan in force moves on by as many rows, as the plant followed it; a new
//! cycle starts at this sample). A sample taken in without adaptation whose applied input
//! is the plan in force's row for it (the loop caught up while the plant followed the
//! plan: its late policy applies the plan's entries) moves the plan on by one row as
//! well; one whose input is anything else (the safe input, a held one) drops the plan, and
//! the input is held until a new plan takes over. Everything here is allocated when the controller is built.

/// The three units of work of one solve (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) struct Units {
    /// The prediction from the committed inputs.
    pub predict: bool,
    /// The condensed QP's Hessian.
    pub build: bool,
    /// The rest of the QP, and its solve begins (all of it without shares).
    pub solve: bool,
    /// The QP solve goes on: a panel of the factorization or a share of active-set
    /// changes (a period after the one it began in; `N ≥ 4`).
    pub solve_more: bool,
    /// The new plan takes over after this period's work.
    pub take_over: bool,
    /// This cycle keeps the last cycle's Hessian and its factorization (no build unit).
    pub reuse: bool,
}

/// The plan in force, the one being computed, and the position in the cycle.
#[derive(Debug, Clone)]
pub(super) struct Replan {
    /// `N`.
    every: usize,
    /// `M`: every `M`-th cycle builds the Hessian (1: every cycle).
    hessian_every: usize,
    /// `N_H ≥ N`: the length of a cycle that builds the Hessian.
    hessian_cycle: usize,
    /// The running cycle's length (`N` or `N_H`) and whether it builds the Hessian.
    len: usize,
    builds: bool,
    /// Cycles begun since the last one that built the Hessian.
    since_build: usize,
    /// The next cycle must build the Hessian (a reset, a dropped build).
    build_due: bool,
    /// Inputs per row, `m`.
    m: usize,
    /// The position in the running cycle, `None` when none runs.
    pos: Option<usize>,
    /// The plan in force: rows for consecutive samples (clipped into the input bounds).
    active: Vec<f64>,
    /// Rows of `active` that hold inputs (0: no plan, the input is held).
    active_rows: usize,
    /// `active` is an MPC solution (else the fallback, held).
    active_valid: bool,
    /// The status bits of the solve that made `active`.
    active_status: u32,
    /// The row of `active` that is the input of the next sample.
    next_row: usize,
    /// The plan being computed (the same layout).
    pending: Vec<f64>,
    pending_rows: usize,
    pending_valid: bool,
    pending_status: u32,
    /// `u_k, …, u_{k+N−1}` of the running cycle (`N m`).
    committed: Vec<f64>,
}

impl Replan {
    /// Buffers for re-planning every `every ≥ 1` samples, `m` inputs, plans of `rows`
    /// rows (the horizon `ℓ`).
    pub fn new(every: usize, m: usize, rows: usize) -> Self {
        let every = every.max(1);
        Self {
            every,
            hessian_every: 1,
            hessian_cycle: every,
            len: every,
            builds: true,
            since_build: 0,
            build_due: true,
            m,
            pos: None,
            active: vec![0.0; rows * m],
            active_rows: 0,
            active_valid: false,
            active_status: 0,
            next_row: 0,
            pending: vec![0.0; rows * m],
            pending_rows: 0,
            pending_valid: false,
            pending_status: 0,
            committed: vec![0.0; every * m],
        }
    }

    /// Cycles that build the Hessian every `m_every ≥ 1` cycles, each `len ≥ N` samples
    /// long; the cycles in between keep it (module docs, "Keeping the Hessian").
    /// Allocates (before the loop).
    pub fn set_hessian_every(&mut self, m_every: usize, len: usize) {
        self.hessian_every = m_every.max(1);
        self.hessian_cycle = len.max(self.every);
        self.committed = vec![0.0; self.hessian_cycle * self.m];
        self.build_due = true;
    }

    /// `N`.
    pub fn every(&self) -> usize {
        self.every
    }

    /// `M`: every `M`-th cycle builds the Hessian (1: every cycle).
    pub fn hessian_every(&self) -> usize {
        self.hessian_every
    }

    /// `N_H`, the length of a cycle that builds the Hessian (`N` when every cycle does).
    pub fn hessian_cycle(&self) -> usize {
        self.hessian_cycle
    }

    /// The next cycle builds the Hessian, whatever the count (the model or the data
    /// changed, or the build failed).
    pub fn build_next(&mut self) {
        self.build_due = true;
    }

    /// The length of the cycle that starts after the running one (as things stand).
    pub fn next_len(&self) -> usize {
        if self.next_builds() {
            self.hessian_cycle
        } else {
            self.every
        }
    }

    /// Whether the next cycle to start builds the Hessian.
    fn next_builds(&self) -> bool {
        self.build_due || self.since_build + 1 >= self.hessian_every
    }

    /// No plan in force and no cycle running (a reset, a new data stream, an
    /// observation).
    pub fn clear(&mut self) {
        self.build_due = true;
        self.pos = None;
        self.active_rows = 0;
        self.active_valid = false;
        self.next_row = 0;
        self.pending_rows = 0;
        self.pending_valid = false;
    }

    /// `lost` samples were not seen before the one at hand: the plant followed the plan
    /// in force over them, and the running cycle (planned from older data) is dropped.
    pub fn skip(&mut self, lost: u64) {
        if lost == 0 {
            return;
        }
        // A dropped cycle that was to build the Hessian leaves it to the next one.
        self.build_due |= self.pos.is_some() && self.builds;
        self.pos = None;
        let lost = usize::try_from(lost).unwrap_or(usize::MAX);
        self.next_row = self.next_row.saturating_add(lost);
    }

    /// Whether `applied` is, bit for bit, the plan in force's row for the sample at hand:
    /// the plant followed the plan over a sample the controller took in without
    /// adaptation.
    pub fn row_applied(&self, applied: &[f64]) -> bool {
        let m = self.m;
        self.next_row < self.active_rows
            && self.active[self.next_row * m..(self.next_row + 1) * m]
                .iter()
                .zip(applied)
                .all(|(a, b)| a.to_bits() == b.to_bits())
    }

    /// The units this period runs, and moves the cycle on by one period. A cycle starts
    /// when none runs.
    pub fn units(&mut self) -> Units {
        let pos = match self.pos {
            Some(pos) => pos,
            None => {
                self.builds = self.next_builds();
                if self.builds {
                    self.since_build = 0;
                    self.build_due = false;
                    self.len = self.hessian_cycle;
                } else {
                    self.since_build += 1;
                    self.len = self.every;
                }
                0
            }
        };
        // The units of the cycle: predict, build (when it builds), solve.
        let k = if self.builds { 3 } else { 2 };
        let lag = k - self.len.min(k);
        let at = |j: usize| j.saturating_sub(lag) == pos;
        let units = Units {
            predict: at(0),
            build: self.builds && at(1),
            solve: at(k - 1),
            solve_more: lag == 0 && pos > k - 1,
            take_over: pos + 1 == self.len,
            reuse: !self.builds,
        };
        self.pos = if units.take_over { None } else { Some(pos + 1) };
        units
    }

    /// The inputs committed at the start of a cycle at sample `k`: `u_k` (`applied`),
    /// then the plan in force for `k+1, …, k+N−1`, holding its last input where it has
    /// no row (or `u_k` when there is no plan). Returns them (`N m`).
    pub fn commit(&mut self, applied: &[f64]) -> &[f64] {
        let m = self.m;
        self.committed[..m].copy_from_slice(&applied[..m]);
        for j in 1..self.len {
            let row = self.next_row.saturating_add(j);
            let (done, rest) = self.committed.split_at_mut(j * m);
            let dst = &mut rest[..m];
            if row < self.active_rows {
                dst.copy_from_slice(&self.active[row * m..(row + 1) * m]);
            } else {
                dst.copy_from_slice(&done[(j - 1) * m..j * m]);
            }
        }
        &self.committed[..self.len * m]
    }

    /// The inputs committed by the last [`Replan::commit`] (`N m`, or `N_H m` in a cycle
    /// that builds the Hessian).
    pub fn committed(&self) -> &[f64] {
        &self.committed[..self.len * self.m]
    }

    /// The last committed input of the running cycle, `u_{k+N−1}`: the move reference
    /// (2.47) of its solve.
    pub fn last_committed(&self) -> &[f64] {
        &self.committed[(self.len - 1) * self.m..self.len * self.m]
    }

    /// The solve's plan: `rows` (`U` of the QP, `ℓ m`), each row clipped by `clip`.
    pub fn set_pending(&mut self, rows: &[f64], status: u32, clip: impl Fn(&mut [f64])) {
        let m = self.m;
        let n = (rows.len() / m).min(self.pending.len() / m);
        self.pending[..n * m].copy_from_slice(&rows[..n * m]);
        for row in self.pending[..n * m].chunks_exact_mut(m) {
            clip(row);
        }
        self.pending_rows = n;
        self.pending_valid = true;
        self.pending_status = status;
    }

    /// The solve fell back: the plan is `input` held, and gives no rows ahead.
    pub fn set_pending_fallback(&mut self, input: &[f64], status: u32) {
        let m = self.m;
        for row in self.pending.chunks_exact_mut(m) {
            row.copy_from_slice(&input[..m]);
        }
        self.pending_rows = self.pending.len() / m;
        self.pending_valid = false;
        self.pending_status = status;
    }

    /// Moves to the next sample: the plan computed takes over when `take_over` (its first
    /// row is the next sample's input), else the plan in force moves on by one row.
    pub fn next_sample(&mut self, take_over: bool) {
        if take_over && self.pending_rows > 0 {
            std::mem::swap(&mut self.active, &mut self.pending);
            self.active_rows = self.pending_rows;
            self.active_valid = self.pending_valid;
            self.active_status = self.pending_status;
            self.pending_rows = 0;
            self.pending_valid = false;
            self.next_row = 0;
        } else {
            self.next_row = self.next_row.saturating_add(1);
        }
    }

    /// The next sample's input from the plan in force, into `u`; `None` (and `u`
    /// untouched) when the plan has no row for it.
    pub fn next_input(&self, u: &mut [f64]) -> Option<u32> {
        let m = self.m;
        if self.next_row >= self.active_rows {
            return None;
        }
        let row = &self.active[self.next_row * m..(self.next_row + 1) * m];
        u[..m].copy_from_slice(row);
        Some(self.active_status)
    }

    /// The rows of the plan in force after the next sample's, into `out` (as many as
    /// fit); none when it is not an MPC solution. Returns how many.
    pub fn rows_after_next(&self, out: &mut [f64]) -> usize {
        let m = self.m;
        if !self.active_valid || m == 0 {
            return 0;
        }
        let from = self.next_row.saturating_add(1).min(self.active_rows);
        let later = &self.active[from * m..self.active_rows * m];
        let mut rows = 0;
        for (dst, src) in out.chunks_exact_mut(m).zip(later.chunks_exact(m)) {
            dst.copy_from_slice(src);
            rows += 1;
        }
        rows
    }
}

#[cfg(test)]
mod tests {
    use super::Replan;

    /// The units per position for N = 1, 2, 3, 5 (module docs).
    #[test]
    fn the_units_follow_the_documented_schedule() {
        let sched = |n: usize| {
            let mut r = Replan::new(n, 1, 8);
            (0..n)
                .map(|_| {
                    let u = r.units();
                    (u.predict, u.build, u.solve, u.take_over)
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(sched(1), vec![(true, true, true, true)]);
        assert_eq!(
            sched(2),
            vec![(true, true, false, false), (false, false, true, true)]
        );
        assert_eq!(
            sched(3),
            vec![
                (true, false, false, false),
                (false, true, false, false),
                (false, false, true, true)
            ]
        );
        let five = sched(5);
        assert_eq!(five[0], (true, false, false, false));
        assert_eq!(five[2], (false, false, true, false));
        assert_eq!(five[3], (false, false, false, false));
        assert_eq!(five[4], (false, false, false, true));
        // The cycle repeats.
        let mut r = Replan::new(2, 1, 8);
        let _ = (r.units(), r.units());
        assert!(r.units().predict);
    }

    /// The committed inputs are u_k then the plan's rows, held past its end; the new plan
    /// takes over with its first row as the next input; lost samples move the plan on.
    #[test]
    fn committed_inputs_and_take_over_follow_the_plan() {
        let mut r = Replan::new(3, 2, 4);
        assert_eq!(r.commit(&[1.0, -1.0]), &[1.0, -1.0, 1.0, -1.0, 1.0, -1.0]);
        let mut u = [0.0; 2];
        assert_eq!(r.next_input(&mut u), None);
        r.set_pending(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0], 7, |row| {
            row[0] = row[0].min(6.0)
        });
        r.next_sample(true);
        assert_eq!(r.next_input(&mut u), Some(7));
        assert_eq!(u, [1.0, 2.0]);
        let mut ahead = [0.0; 8];
        assert_eq!(r.rows_after_next(&mut ahead), 3);
        assert_eq!(&ahead[..6], &[3.0, 4.0, 5.0, 6.0, 6.0, 8.0]);
        // A cycle starting at the sample of row 0: rows 1 and 2 are committed.
        assert_eq!(r.commit(&[1.0, 2.0]), &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        r.next_sample(false);
        assert_eq!(r.next_input(&mut u), Some(7));
        assert_eq!(u, [3.0, 4.0]);
        // From row 1: row 2, row 3, then held.
        assert_eq!(r.commit(&[3.0, 4.0]), &[3.0, 4.0, 5.0, 6.0, 6.0, 8.0]);
        r.skip(1);
        r.next_sample(false);
        assert_eq!(r.next_input(&mut u), Some(7));
        assert_eq!(u, [6.0, 8.0]);
        assert_eq!(r.commit(&[6.0, 8.0]), &[6.0, 8.0, 6.0, 8.0, 6.0, 8.0]);
        r.next_sample(false);
        assert_eq!(r.next_input(&mut u), None);
        assert_eq!(r.rows_after_next(&mut ahead), 0);
        // A fallback plan holds its input and gives no rows ahead.
        r.set_pending_fallback(&[0.5, 0.5], 9);
        r.next_sample(true);
        assert_eq!(r.next_input(&mut u), Some(9));
        assert_eq!(u, [0.5, 0.5]);
        assert_eq!(r.rows_after_next(&mut ahead), 0);
    }

    /// With a build every third cycle, cycles of `N_H = 7` build (predict, build, solve),
    /// the two after them keep the Hessian in `N = 4` (predict, solve); a build cycle
    /// dropped by lost samples leaves the build to the next cycle.
    #[test]
    fn cycles_that_build_the_hessian_take_their_own_length() {
        let mut r = Replan::new(4, 1, 16);
        r.set_hessian_every(3, 7);
        let mut cycle = || {
            let mut units = vec![r.units()];
            while !units.last().unwrap().take_over {
                units.push(r.units());
            }
            units
        };
        for _ in 0..2 {
            let build = cycle();
            assert_eq!(build.len(), 7);
            assert!(build[0].predict && build[1].build && build[2].solve);
            assert!(build.iter().all(|u| !u.reuse));
            assert!(build[3..6].iter().all(|u| u.solve_more));
            for _ in 0..2 {
                let kept = cycle();
                assert_eq!(kept.len(), 4);
                assert!(kept[0].predict && kept[1].solve && kept[2].solve_more);
                assert!(kept.iter().all(|u| u.reuse && !u.build));
            }
        }
        assert_eq!(r.next_len(), 7);
        let first = r.units();
        assert!(first.predict && !first.reuse);
        r.skip(1);
        assert_eq!(r.next_len(), 7);
        assert!(!r.units().reuse);
    }
}
