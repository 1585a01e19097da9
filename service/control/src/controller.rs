//! The controller interface: what a controller gets at sample `k` and what it returns.
//!
//! A controller is a pure kernel: it gets the signals of sample `k` (measurement `y_k`,
//! performance `z_k`, command `r_k`, as in Figure 3.1 of the dissertation) and writes the
//! control input `u_k`. It is built (allocating) from its parameters before the real-time
//! thread starts; its [`Controller::step`] must not allocate, lock, do I/O or panic. The
//! loop around it (waiting, publishing, deadline policy, logging) knows nothing of what is
//! inside. The interface speaks in its own types: [`Dimensions`] for the channel counts and
//! [`status`] bits for what a step did; the service maps them to the wire contract.

pub use crate::output_limits::OutputLimits;

/// The channels a controller reads (`n_y`, `n_z`, `n_r`) and writes (`n_u`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Dimensions {
    /// Number of measurements `y`.
    pub n_y: usize,
    /// Number of performance variables `z`.
    pub n_z: usize,
    /// Number of commands `r`.
    pub n_r: usize,
    /// Number of control inputs `u`.
    pub n_u: usize,
}

impl Dimensions {
    /// The four counts.
    pub fn new(n_y: usize, n_z: usize, n_r: usize, n_u: usize) -> Self {
        Self { n_y, n_z, n_r, n_u }
    }
}

/// The bits a [`Controller::step`] returns (0 is a normal step).
pub mod status {
    /// The controller ran normally and `u` is its output.
    pub const OK: u32 = 0;
    /// A finite value of the law was clipped to the configured limits
    /// ([`crate::output_limits`]), or PCAC's first move lies on an input bound.
    pub const SATURATED: u32 = 1 << 0;
    /// The controller reported an internal fault: its law gave a value that is not finite
    /// (replaced by the rule of [`crate::output_limits`]), a non-finite input held, adaptive
    /// state reset by its guard, a diverging state reset.
    pub const CONTROLLER_FAULT: u32 = 1 << 1;
    /// The controller could not compute its law for this sample (for example PCAC's
    /// receding-horizon problem was infeasible or not solved within its iteration cap) and
    /// `u` is its fallback input.
    pub const FALLBACK: u32 = 1 << 2;
}

/// Maximum number of internal signals a controller exposes to the signal log.
pub const MAX_INTERNALS: usize = 16;

/// The signals of sample `k` handed to a controller; slices have the configured lengths.
///
/// `u_applied` and `lost` tell a controller what happened between its calls when the loop
/// is not perfect: the plant may have held an older input because an actuation arrived
/// after its deadline, and samples may never have reached the service. A controller whose
/// state depends on the past inputs (RCAC's regressor and filtered input) uses them to
/// keep that state equal to what the plant saw.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepInput<'a> {
    /// Sample index `k`.
    pub seq: u64,
    /// Measurement `y_k`.
    pub y: &'a [f64],
    /// Performance variable `z_k`.
    pub z: &'a [f64],
    /// Command `r_k`.
    pub r: &'a [f64],
    /// The input the plant actually applied after sample `k − 1` (held over the period
    /// ending at sample `k`), when the plant reports it (contract flag
    /// `measurement_flags::U_APPLIED`); `None` when unknown.
    pub u_applied: Option<&'a [f64]>,
    /// Samples lost between the previous call and this one (`k − k_prev − 1`); 0 normally.
    pub lost: u64,
}

/// A controller the service can run.
pub trait Controller: Send {
    /// A short name for reports ("lti", "rcac", …).
    fn kind(&self) -> &'static str;
    /// The channels it reads (`n_y`, `n_z`, `n_r`) and writes (`n_u`).
    fn counts(&self) -> Dimensions;
    /// Computes `u_k` from the signals of sample `k`; `u` has length `n_u`. Returns
    /// [`status`] bits (`OK`, `SATURATED`, `CONTROLLER_FAULT`).
    ///
    /// Must not allocate, lock, do I/O or panic, and must leave `u` finite.
    fn step(&mut self, input: &StepInput<'_>, u: &mut [f64]) -> u32;
    /// Takes in sample `k` without being asked for an input to apply: the loop received it
    /// too late (a newer sample was already waiting), so no actuation of it will be
    /// applied. A controller with memory must still record it so that its state stays
    /// aligned with the plant's samples; `u` is scratch of length `n_u`.
    ///
    /// The sample must enter the controller's data (regressors, histories), so that the
    /// inputs that follow are computed from what the plant really did. A controller may
    /// skip its adaptation for an observed sample, so that a loop that is behind catches
    /// up sooner (RCAC does; PCAC identifies from it). The default runs
    /// [`Controller::step`] and discards the output. Same real-time rules as `step`.
    fn observe(&mut self, input: &StepInput<'_>, u: &mut [f64]) {
        let _ = self.step(input, u);
    }
    /// Returns to the initial state: what was learned and the data history (the
    /// configuration can ask for it when a new plant session begins).
    fn reset(&mut self);
    /// A new data stream begins (a new plant session: a restarted or replaced plant
    /// process): forget the data history (regressors, filter states, the held input, the
    /// forgetting windows) and keep what was learned ([`crate::learned`]). The default is
    /// [`Controller::reset`], which is right for a controller that learns nothing.
    /// Same real-time rules as `step`.
    fn restart_data(&mut self) {
        self.reset();
    }
    /// Visits what the controller learned, as named blocks whose names, order and lengths
    /// depend only on the configuration ([`crate::learned`]); the service copies them into
    /// a checkpoint from the real-time loop. Must not allocate. The default visits nothing.
    fn learned(&self, _visit: &mut dyn FnMut(&'static str, &[f64])) {}
    /// Takes what a checkpoint saved from [`Controller::learned`] into a controller just
    /// built from the same configuration, checking the values first (finite, a positive
    /// definite covariance within the guard); on an error the controller is left in its
    /// initial state. Called before the real-time loop; may allocate.
    ///
    /// # Errors
    ///
    /// What is wrong with which block.
    fn restore_learned(&mut self, saved: &crate::learned::Learned<'_>) -> Result<(), String> {
        if saved.is_empty() {
            Ok(())
        } else {
            Err(format!("the {} controller learns nothing", self.kind()))
        }
    }
    /// The ahead form of this controller ([`crate::ahead`]): `Some` when its input for
    /// sample `k` depends only on the data up to `k − 1`, so that the loop can publish it
    /// before computing (answer-first) or as soon as sample `k − 1` is in (send-ahead).
    /// Whether it is `Some` depends only on the configuration. The default is `None`:
    /// the controller runs compute-first through [`Controller::step`].
    fn ahead(&mut self) -> Option<&mut dyn crate::ahead::Ahead> {
        None
    }
    /// Called once on the real-time thread before its loop starts (before allocations are
    /// counted there): a controller whose libraries keep lazily created per-thread state
    /// (e.g. the matrix-multiply scratch of PCAC's QP solver) creates it here, so that the
    /// first real-time step does not allocate. The default does nothing.
    fn prepare_thread(&mut self) {}
    /// The model-following error `e_k = y_k − y_{m,k}` of the latest step, for a
    /// controller that follows a reference model (APPC and RC-MRAC, chapter 4); the service
    /// reports its norm (4.85). `None` (the default) for the others. Must not allocate.
    fn model_following_error(&self) -> Option<f64> {
        None
    }
    /// Names of the internal signals written by [`Controller::internals`].
    fn internal_names(&self) -> Vec<String> {
        Vec::new()
    }
    /// What the controller counted so far, for the run report (e.g. PCAC's solved,
    /// infeasible and unsolved QPs, identification resets). Called outside the real-time
    /// loop; may allocate.
    fn counters(&self) -> Vec<(&'static str, u64)> {
        Vec::new()
    }
    /// Writes up to [`MAX_INTERNALS`] internal signals (for the signal log) and returns how
    /// many. Must not allocate.
    fn internals(&self, _out: &mut [f64]) -> usize {
        0
    }
    /// How often an adaptive controller's update ran on the steps it was asked to adapt
    /// (closed loop) and, per cause, how often it was suspended; the run report gives it
    /// and the verdict fails a run in which it was suspended on most steps. `None` (the
    /// default): the controller does not adapt, or does not count. Called outside the
    /// real-time loop; may allocate.
    fn adaptation(&self) -> Option<Adaptation> {
        None
    }
    /// Freezes (`on` false) or resumes (`on` true) the adaptation on an operator's command:
    /// a frozen controller keeps computing its law with what it has learned and keeps its
    /// data histories up to date, but does not update its estimate; the steps it skips are
    /// counted in [`Adaptation::frozen`], not as suspensions. Returns false, changing
    /// nothing, for a controller that does not adapt (the default). Same real-time rules
    /// as `step`.
    fn set_adaptation(&mut self, _on: bool) -> bool {
        false
    }
    /// The parameters an operator may change while the controller runs, in a fixed order
    /// ([`Tunable`]); the default declares none.
    fn tunables(&self) -> &'static [Tunable] {
        &[]
    }
    /// The value of tunable `index` of [`Controller::tunables`] in force (`None` for an
    /// index out of range, or a tunable this configuration does not use).
    fn tunable(&self, _index: usize) -> Option<f64> {
        None
    }
    /// Sets tunable `index` to `value`, which the caller checked with [`Tunable::admits`];
    /// returns false, changing nothing, when this configuration does not use it. Takes
    /// effect from the next step. Same real-time rules as `step`.
    fn set_tunable(&mut self, _index: usize, _value: f64) -> bool {
        false
    }
}

/// A parameter an operator may change while a controller runs
/// ([`Controller::tunables`]).
#[derive(Debug, Clone, Copy)]
pub struct Tunable {
    /// Its name in the configuration (`"alpha"`).
    pub name: &'static str,
    /// The values the law admits, as written in the docs (`"(0, 1]"`).
    pub range: &'static str,
    /// Whether the law admits `value` (the same check as the parameter's at build time).
    pub admits: fn(f64) -> bool,
}

/// How often an adaptive controller's update ran and why it did not
/// ([`Controller::adaptation`]). The steps before the controller's own start of adaptation
/// (RCAC's `k_w`) count in neither.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Adaptation {
    /// Closed-loop steps whose update ran.
    pub updated: u64,
    /// Closed-loop steps whose update was suspended, per cause (a short phrase: "a gap in
    /// its data", "a bad sample").
    pub suspended: Vec<(&'static str, u64)>,
    /// Closed-loop steps whose update the operator froze ([`Controller::set_adaptation`]):
    /// neither updated nor suspended.
    pub frozen: u64,
}

impl Adaptation {
    /// The cause "a bridged gap in its windows": lost samples, bridged, are still in the
    /// data the update reads.
    pub const BRIDGED_GAP: &'static str = "a bridged gap in its windows";
    /// The cause "a bad sample": a non-finite sample, replaced, is in the data.
    pub const BAD_SAMPLE: &'static str = "a bad sample";

    /// All suspended steps.
    pub fn suspended(&self) -> u64 {
        self.suspended.iter().map(|(_, n)| n).sum()
    }
}
