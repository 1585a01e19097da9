//! The [`Outbox`] of a replay: each actuation the replayed loop publishes is taken against
//! the next `Publish` entry of the record, which also gives back what the real publisher
//! returned then (sent or not, and its time: the response time the deadline policy
//! judged).

use super::comparison::Comparison;
use super::difference::{Difference, first_difference};
use crate::record::{Entry, Located, RecordError, RecordReader};
use crate::runtime::Outbox;
use ipc_types::Actuation;

/// Why a bit-for-bit replay stopped before the end of the record.
#[derive(Debug, Clone, PartialEq)]
pub enum Stop {
    /// A replayed actuation differs from the logged one, or one side has an actuation the
    /// other has not.
    Differ {
        /// The entry of the record where it showed.
        index: u64,
        /// Its byte offset.
        offset: u64,
        /// The sample being answered (the logged actuation's `reply_to`, else the replayed).
        reply_to: u64,
        /// The actuation's `seq`.
        seq: u64,
        /// What differs.
        what: Difference,
    },
    /// The record cannot be read further: a gap, a truncated entry.
    Record(RecordError),
}

/// How a replay compares.
pub enum Compare<'a> {
    /// Bit for bit: the first difference stops the replay.
    BitForBit,
    /// Open loop, another configuration: every pair goes to the comparison.
    OpenLoop(&'a mut Comparison),
}

/// The replay's outbox over the record being read.
pub struct ReplayOutbox<'a> {
    pub(super) reader: &'a mut RecordReader,
    pub(super) compare: Compare<'a>,
    pub(super) n_u: usize,
    /// The receive time of the input being replayed: the time returned for an actuation
    /// the record does not have.
    pub(super) t_recv_ns: u64,
    /// Actuations compared equal (bit for bit) or paired (open loop).
    pub(super) compared: u64,
    /// Set when the replay must stop.
    pub(super) stop: Option<Stop>,
}

impl ReplayOutbox<'_> {
    /// The next entry if it is a `Publish`, taken; `Ok(None)` when the next is another
    /// entry or the end.
    pub(super) fn take_publish(&mut self) -> Result<Option<Located>, RecordError> {
        match self.reader.peek()? {
            Some(Located {
                entry: Entry::Publish { .. },
                ..
            }) => self.reader.next_entry(),
            _ => Ok(None),
        }
    }
}

impl Outbox for ReplayOutbox<'_> {
    fn publish(&mut self, act: &mut Actuation) -> (bool, u64) {
        let fallback = (true, self.t_recv_ns);
        if self.stop.is_some() {
            return fallback;
        }
        let logged = match self.take_publish() {
            Ok(l) => l,
            Err(e) => {
                self.stop = Some(Stop::Record(e));
                return fallback;
            }
        };
        let Some(Located {
            index,
            offset,
            entry:
                Entry::Publish {
                    act: logged,
                    ok,
                    t_pub_ns,
                },
        }) = logged
        else {
            match &mut self.compare {
                Compare::BitForBit => {
                    let (index, offset) = match self.reader.peek() {
                        Ok(Some(l)) => (l.index, l.offset),
                        _ => (0, 0),
                    };
                    self.stop = Some(Stop::Differ {
                        index,
                        offset,
                        reply_to: act.reply_to,
                        seq: act.seq,
                        what: Difference {
                            field: "actuation".into(),
                            logged: "none published here".into(),
                            replayed: format!("one for sample {} (status {})", act.seq, act.status),
                        },
                    });
                }
                Compare::OpenLoop(c) => c.only_replayed(),
            }
            return fallback;
        };
        act.t_publish_ns = t_pub_ns;
        match &mut self.compare {
            Compare::BitForBit => match first_difference(&logged, act, self.n_u) {
                None => self.compared += 1,
                Some(what) => {
                    self.stop = Some(Stop::Differ {
                        index,
                        offset,
                        reply_to: logged.reply_to,
                        seq: logged.seq,
                        what,
                    })
                }
            },
            Compare::OpenLoop(c) => {
                c.pair(&logged, act);
                self.compared += 1;
            }
        }
        (ok, t_pub_ns)
    }
}
