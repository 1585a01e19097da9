//! The per-interval measurement set recorded by the RT thread: four pre-sized
//! histograms, the worst cycles and the over-budget count.

use hdrhistogram::Histogram;

use super::CycleTiming;

/// Lowest value the histograms distinguish from 0, in ns.
pub const LOWEST_DISCERNIBLE_NS: u64 = 1;
/// Highest value the histograms track (10 s), in ns. Larger values are clamped to it.
pub const HIGHEST_TRACKABLE_NS: u64 = 10_000_000_000;
/// Number of significant decimal figures kept by the histograms (relative error ≤ 0.1 %).
pub const SIGNIFICANT_FIGURES: u8 = 3;
/// How many of the largest response times [`WorstCycles`] keeps.
pub const WORST_K: usize = 10;

/// The four latency distributions of the control loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HistogramKind {
    /// Sample timestamp → receipt by the RT thread.
    Wakeup,
    /// Controller step duration.
    Compute,
    /// Sample timestamp → publication of the actuation.
    Response,
    /// Period jitter of the receipt times.
    Jitter,
}

impl HistogramKind {
    /// All kinds, in report order.
    pub const ALL: [HistogramKind; 4] = [
        HistogramKind::Wakeup,
        HistogramKind::Compute,
        HistogramKind::Response,
        HistogramKind::Jitter,
    ];

    /// The short name used in file names (`<name>.hlog`, `<name>.hgrm`), interval-log tags
    /// and reports.
    pub const fn name(self) -> &'static str {
        match self {
            HistogramKind::Wakeup => "wakeup",
            HistogramKind::Compute => "compute",
            HistogramKind::Response => "response",
            HistogramKind::Jitter => "jitter",
        }
    }

    /// Position in [`HistogramKind::ALL`].
    pub const fn index(self) -> usize {
        match self {
            HistogramKind::Wakeup => 0,
            HistogramKind::Compute => 1,
            HistogramKind::Response => 2,
            HistogramKind::Jitter => 3,
        }
    }
}

/// The `K =` [`WORST_K`] largest response times seen, with their sequence numbers.
///
/// A fixed array, so offering a value never allocates. The smallest kept entry is
/// remembered, so the common case (a value below every kept one) costs one comparison;
/// only a new top-K value triggers a scan of the `K` entries. On ties the earlier cycle
/// is kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WorstCycles {
    /// `(seq, ns)` pairs; only the first `len` are valid, in no particular order.
    entries: [(u64, u64); WORST_K],
    len: usize,
    /// Index of the smallest valid entry (meaningful once `len == WORST_K`).
    min_index: usize,
}

impl Default for WorstCycles {
    fn default() -> Self {
        Self::new()
    }
}

impl WorstCycles {
    /// An empty tracker.
    pub const fn new() -> Self {
        Self {
            entries: [(0, 0); WORST_K],
            len: 0,
            min_index: 0,
        }
    }

    /// Offers the cycle `seq` with value `ns`; keeps it if it is among the `K` largest.
    #[inline]
    pub fn offer(&mut self, seq: u64, ns: u64) {
        if self.len < WORST_K {
            if let Some(slot) = self.entries.get_mut(self.len) {
                *slot = (seq, ns);
            }
            self.len += 1;
            if self.len == WORST_K {
                self.update_min_index();
            }
        } else {
            match self.entries.get_mut(self.min_index) {
                Some(slot) if ns > slot.1 => {
                    *slot = (seq, ns);
                    self.update_min_index();
                }
                _ => {}
            }
        }
    }

    /// Finds the entry to evict next: the smallest value and, among equal smallest
    /// values, the latest cycle (so that the earliest ones are kept).
    fn update_min_index(&mut self) {
        let mut min_index = 0;
        let mut min = (u64::MAX, 0u64);
        for (i, &(seq, ns)) in self.entries.iter().enumerate().take(self.len) {
            if ns < min.0 || (ns == min.0 && seq > min.1) {
                min = (ns, seq);
                min_index = i;
            }
        }
        self.min_index = min_index;
    }

    /// Number of entries kept (≤ [`WORST_K`]).
    pub fn len(&self) -> usize {
        self.len
    }

    /// `true` if nothing was offered since the last [`clear`](Self::clear).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The kept `(seq, ns)` pairs, in no particular order.
    pub fn entries(&self) -> &[(u64, u64)] {
        &self.entries[..self.len]
    }

    /// The kept `(seq, ns)` pairs, largest value first (ties: lower sequence number
    /// first). Returns a fixed array and the number of valid entries; does not allocate.
    pub fn sorted(&self) -> ([(u64, u64); WORST_K], usize) {
        let mut out = self.entries;
        out[..self.len].sort_unstable_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        (out, self.len)
    }

    /// Forgets every entry.
    pub fn clear(&mut self) {
        self.len = 0;
        self.min_index = 0;
    }

    /// Offers every entry of `other` (merging two trackers).
    pub fn merge(&mut self, other: &WorstCycles) {
        for &(seq, ns) in other.entries() {
            self.offer(seq, ns);
        }
    }
}

/// One interval's worth of loop measurements.
///
/// Four histograms of range [`LOWEST_DISCERNIBLE_NS`] … [`HIGHEST_TRACKABLE_NS`] with
/// [`SIGNIFICANT_FIGURES`] significant figures and auto-resize off (about 200 KiB each),
/// the [`WorstCycles`] of the response time, the number of response times over the
/// budget, the number of cycles recorded and the interval's monotonic start and end.
///
/// Constructing one allocates; [`record`](Self::record) never does.
#[derive(Clone, Debug)]
pub struct LoopHistograms {
    histograms: [Histogram<u64>; 4],
    worst: WorstCycles,
    budget_ns: u64,
    over_budget: u64,
    cycles: u64,
    interval_start_ns: u64,
    interval_end_ns: u64,
}

fn new_histogram() -> Histogram<u64> {
    // The bounds are constants that satisfy every precondition of `new_with_bounds`
    // (low ≥ 1, high ≥ 2·low, sigfig ≤ 5), so this cannot fail.
    let mut h = Histogram::new_with_bounds(
        LOWEST_DISCERNIBLE_NS,
        HIGHEST_TRACKABLE_NS,
        SIGNIFICANT_FIGURES,
    )
    .expect("constant histogram bounds are valid");
    h.auto(false);
    h
}

impl LoopHistograms {
    /// Allocates an empty set. `budget_ns` is the response-time budget: a cycle whose
    /// response time is strictly greater counts as over budget (`u64::MAX` disables the
    /// count).
    pub fn new(budget_ns: u64) -> Self {
        Self {
            histograms: [
                new_histogram(),
                new_histogram(),
                new_histogram(),
                new_histogram(),
            ],
            worst: WorstCycles::new(),
            budget_ns,
            over_budget: 0,
            cycles: 0,
            interval_start_ns: 0,
            interval_end_ns: 0,
        }
    }

    /// Records one cycle. Never allocates, locks or panics: values outside the range are
    /// clamped to it. The jitter histogram is only fed when `period_jitter_ns` is `Some`.
    #[inline]
    pub fn record(&mut self, t: &CycleTiming) {
        let [wakeup, compute, response, jitter] = &mut self.histograms;
        wakeup.saturating_record(t.wakeup_ns);
        compute.saturating_record(t.compute_ns);
        response.saturating_record(t.response_ns);
        if let Some(j) = t.period_jitter_ns {
            jitter.saturating_record(j);
        }
        if t.response_ns > self.budget_ns {
            self.over_budget = self.over_budget.saturating_add(1);
        }
        self.worst.offer(t.seq, t.response_ns);
        self.cycles = self.cycles.saturating_add(1);
    }

    /// Empties the set, keeping its configuration and its allocation. Costs a pass over
    /// the counts arrays: do it outside the RT thread.
    pub fn reset(&mut self) {
        for h in &mut self.histograms {
            h.reset();
        }
        self.worst.clear();
        self.over_budget = 0;
        self.cycles = 0;
        self.interval_start_ns = 0;
        self.interval_end_ns = 0;
    }

    /// Adds `other` into `self` (histogram counts, worst cycles, over-budget and cycle
    /// counts; the interval becomes the union of both). `other`'s over-budget count was
    /// taken against `other`'s budget. Does not allocate when both sets have the default
    /// configuration; meant for the non-RT side.
    pub fn add(&mut self, other: &LoopHistograms) {
        for (mine, theirs) in self.histograms.iter_mut().zip(other.histograms.iter()) {
            if mine.add(theirs).is_err() {
                // Only possible with a foreign configuration: fall back to clamped
                // re-recording, which cannot fail.
                for v in theirs.iter_recorded() {
                    mine.saturating_record_n(v.value_iterated_to(), v.count_at_value());
                }
            }
        }
        self.worst.merge(&other.worst);
        self.over_budget = self.over_budget.saturating_add(other.over_budget);
        self.cycles = self.cycles.saturating_add(other.cycles);
        if other.interval_start_ns != 0
            && (self.interval_start_ns == 0 || other.interval_start_ns < self.interval_start_ns)
        {
            self.interval_start_ns = other.interval_start_ns;
        }
        self.interval_end_ns = self.interval_end_ns.max(other.interval_end_ns);
    }

    /// The histogram of one kind.
    pub fn histogram(&self, kind: HistogramKind) -> &Histogram<u64> {
        &self.histograms[kind.index()]
    }

    /// Wake-up latency histogram (ns).
    pub fn wakeup(&self) -> &Histogram<u64> {
        self.histogram(HistogramKind::Wakeup)
    }

    /// Controller step duration histogram (ns).
    pub fn compute(&self) -> &Histogram<u64> {
        self.histogram(HistogramKind::Compute)
    }

    /// Response time histogram (ns).
    pub fn response(&self) -> &Histogram<u64> {
        self.histogram(HistogramKind::Response)
    }

    /// Period jitter histogram (ns).
    pub fn jitter(&self) -> &Histogram<u64> {
        self.histogram(HistogramKind::Jitter)
    }

    /// The largest response times with their sequence numbers.
    pub fn worst(&self) -> &WorstCycles {
        &self.worst
    }

    /// The response-time budget in ns.
    pub fn budget_ns(&self) -> u64 {
        self.budget_ns
    }

    /// Number of cycles whose response time exceeded the budget.
    pub fn over_budget(&self) -> u64 {
        self.over_budget
    }

    /// Number of cycles recorded.
    pub fn cycles(&self) -> u64 {
        self.cycles
    }

    /// Monotonic time (ns) at which the interval started; 0 if not started.
    pub fn interval_start_ns(&self) -> u64 {
        self.interval_start_ns
    }

    /// Monotonic time (ns) at which the interval ended; 0 while it is still open.
    pub fn interval_end_ns(&self) -> u64 {
        self.interval_end_ns
    }

    /// Marks the start of the interval (monotonic ns).
    #[inline]
    pub fn begin_interval(&mut self, start_ns: u64) {
        self.interval_start_ns = start_ns;
        self.interval_end_ns = 0;
    }

    /// Marks the end of the interval (monotonic ns).
    #[inline]
    pub fn end_interval(&mut self, end_ns: u64) {
        self.interval_end_ns = end_ns;
    }
}
