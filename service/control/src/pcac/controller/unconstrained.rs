//! The PCAC step's use of the unconstrained fast path ([`crate::mpc::fast_path`], module
//! docs of [`super`], step 4): the Riccati minimizer of (2.48) on the realization the
//! prediction used, accepted as the QP's solution when it meets (2.49)–(2.51); and the
//! accessors that tell which path the last step took.

use super::Pcac;
use crate::bocf::IdentifiedModel;
use crate::mpc::fast_path::FastPath;
use crate::mpc::qp::{DenseQpSolver, QpProblem};

/// [`Pcac::solution`] from the fields it reads (so that the step can borrow the others):
/// `fast`'s `U*` when `fast_used`, else `solver`'s `U`.
pub(super) fn solution_of<'a>(
    fast: &'a Option<FastPath>,
    fast_used: bool,
    solver: &'a DenseQpSolver,
) -> &'a [f64] {
    match fast {
        Some(fast) if fast_used => fast.u(),
        _ => solver.x(),
    }
}

impl Pcac {
    /// With the fast path, keeps the realization the prediction just used (the identified
    /// model's, or with an augmented `K̄` the closed loop's (7.56)–(7.57)) for
    /// [`Pcac::try_fast_path`], which may run a period later when re-planning
    /// ([`super::super::replan`]), after identification has moved the model on. False when
    /// there is a fast path and the realization was refused (then it is not tried).
    /// Allocation-free.
    pub(super) fn keep_fast_model(&mut self) -> bool {
        let Some(fast) = &mut self.fast else {
            return false;
        };
        match &self.aug {
            None => fast.keep_model(&self.model.realization()),
            Some(aug) => fast.keep_model(&aug.view(&self.model).realization()),
        }
    }

    /// The rest of a deferred prediction ([`crate::bocf::HorizonPrediction::defer_horizon`]), for a QP,
    /// on the realization the fast path kept (the one the prediction used, whichever
    /// period this runs in); true when the prediction is complete. Allocation-free.
    pub(super) fn complete_prediction(&mut self) -> bool {
        if self.pred.is_complete() {
            return true;
        }
        let Some(real) = self.fast.as_ref().and_then(FastPath::kept_realization) else {
            return false;
        };
        self.fast_model && self.pred.complete(&real).is_ok()
    }

    /// The rest of a deferred prediction in the period of the prediction itself, on the
    /// model it used (the identified model, or the closed loop with an augmented `K̄`;
    /// never deferred with the internal model), when the fast path could not keep that
    /// realization. True when the prediction is complete. Allocation-free.
    pub(super) fn complete_prediction_now(&mut self) -> bool {
        if self.pred.is_complete() {
            return true;
        }
        let done = match (&self.aug, &self.tones) {
            (Some(aug), _) => self.pred.complete(&aug.view(&self.model).realization()),
            (None, None) => self.pred.complete(&self.model.realization()),
            (None, Some(_)) => return false,
        };
        done.is_ok()
    }

    /// Tries the fast path on the last prediction (`self.pred`: the start state `x_{1|k}`,
    /// `x_{N|k}` or `x̂_k`, the Markov parameters and the free response) and the
    /// realization it used ([`Pcac::keep_fast_model`]), with the move reference
    /// `self.u_ref` and the command `self.reference`; true when its `U*` is the QP's
    /// solution. False without a fast path. Allocation-free.
    pub(super) fn try_fast_path(&mut self) -> bool {
        let Some(fast) = &mut self.fast else {
            return false;
        };
        self.fast_model
            && fast.solve_kept(
                self.pred.one_step_state(),
                &self.u_ref,
                &self.reference,
                self.pred.free_response(),
                self.pred.markov(),
            )
    }

    /// The last MPC step's solution `U`: the fast path's `U*` when it took the fast path,
    /// else the solver's ([`solution_of`]).
    pub(super) fn solution(&self) -> &[f64] {
        solution_of(&self.fast, self.fast_used, &self.solver)
    }

    /// Whether the last MPC step's input came from the unconstrained fast path
    /// ([`super::PcacCounters::fast_path`] counts such steps).
    pub fn fast_path_taken(&self) -> bool {
        self.fast_used
    }

    /// The condensed QP of the last MPC step: [`Pcac::last_problem`] when the step
    /// condensed, condensed now when it took the fast path (which does not condense). For
    /// comparisons with other solvers, not for the real-time step: it costs a
    /// [`crate::mpc::condense::Condenser::build`] (allocating nothing, and changing nothing
    /// the next step uses). `None` only when that build refuses the step's data.
    pub fn condensed_problem(&mut self) -> Option<QpProblem<'_>> {
        if !self.fast_used {
            return Some(self.cond.problem());
        }
        if !self.complete_prediction() {
            return None;
        }
        self.cond
            .build(
                self.pred.markov(),
                self.pred.free_response(),
                &self.u_ref,
                &self.reference,
            )
            .ok()
    }
}
