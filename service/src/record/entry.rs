//! One entry of a record: what the loop was handed or published, encoded little-endian
//! into the fixed size of its kind ([`RecordLayout`]), and decoded back.
//!
//! Encoding writes into a caller's buffer of at least [`RecordLayout::max_entry_bytes`]
//! and neither allocates nor fails: it runs on the RT thread ([`super::Recorder`]).

use super::layout::{ENTRY_HEAD_BYTES, EntryKind, RecordLayout};
use ipc_types::{Actuation, ChannelCounts, MAX_PLAN, Measurement};

/// A decoded entry.
// One entry is decoded at a time and moved little: boxing the actuation would allocate per
// entry for nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy)]
pub enum Entry {
    /// A measurement handed to `LoopCore::handle`, received at `t_recv_ns`.
    Handle {
        /// The measurement as the loop saw it (channels past the record's counts are zero).
        m: Measurement,
        /// Its receive time, ns (`CLOCK_MONOTONIC`).
        t_recv_ns: u64,
    },
    /// A measurement taken in too late (`LoopCore::observe`).
    Observe {
        /// The measurement.
        m: Measurement,
    },
    /// The next sample comes from another publisher.
    NewPeer,
    /// The loop declared the plant silent at `now_ns`.
    WentSilent {
        /// The time given to `LoopCore::on_idle`.
        now_ns: u64,
    },
    /// The end mark; its index is the number of entries the loop offered.
    End,
    /// An operator command applied before the next entry.
    Operator {
        /// The request's id.
        request_id: u64,
        /// Its wire code ([`ipc_types::operator::command`]).
        command: u32,
        /// The tunable's index (`set-tunable`).
        index: u32,
        /// The value (`set-tunable`).
        value: f64,
    },
    /// An actuation the loop published.
    Publish {
        /// The actuation (plan rows past the record's plan length are zero).
        act: Actuation,
        /// The publisher sent it.
        ok: bool,
        /// The time the publisher returned, ns.
        t_pub_ns: u64,
    },
}

impl Entry {
    /// Its kind.
    pub fn kind(&self) -> EntryKind {
        match self {
            Entry::Handle { .. } => EntryKind::Handle,
            Entry::Observe { .. } => EntryKind::Observe,
            Entry::NewPeer => EntryKind::NewPeer,
            Entry::WentSilent { .. } => EntryKind::WentSilent,
            Entry::Publish { .. } => EntryKind::Publish,
            Entry::End => EntryKind::End,
            Entry::Operator { .. } => EntryKind::Operator,
        }
    }

    /// Encodes it as entry `index` into `buf` (at least `layout.max_entry_bytes()` long);
    /// returns the bytes written.
    pub fn encode(&self, layout: &RecordLayout, index: u64, buf: &mut [u8]) -> usize {
        match self {
            Entry::Handle { m, t_recv_ns } => {
                encode_measurement(layout, EntryKind::Handle, index, m, *t_recv_ns, buf)
            }
            Entry::Observe { m } => {
                encode_measurement(layout, EntryKind::Observe, index, m, 0, buf)
            }
            Entry::NewPeer => encode_marker(EntryKind::NewPeer, index, None, buf),
            Entry::End => encode_marker(EntryKind::End, index, None, buf),
            Entry::WentSilent { now_ns } => {
                encode_marker(EntryKind::WentSilent, index, Some(*now_ns), buf)
            }
            Entry::Publish { act, ok, t_pub_ns } => {
                encode_publish(layout, index, act, *ok, *t_pub_ns, buf)
            }
            Entry::Operator {
                request_id,
                command,
                index: tunable,
                value,
            } => encode_operator(index, *request_id, *command, *tunable, *value, buf),
        }
    }
}

/// A little-endian writer into a byte slice; bytes past its end are not written.
struct Put<'a> {
    buf: &'a mut [u8],
    at: usize,
}

impl Put<'_> {
    #[inline]
    fn bytes<const N: usize>(&mut self, b: [u8; N]) {
        if let Some(dst) = self.buf.get_mut(self.at..self.at + N) {
            dst.copy_from_slice(&b);
        }
        self.at += N;
    }
    #[inline]
    fn u8(&mut self, v: u8) {
        self.bytes([v]);
    }
    #[inline]
    fn u16(&mut self, v: u16) {
        self.bytes(v.to_le_bytes());
    }
    #[inline]
    fn u32(&mut self, v: u32) {
        self.bytes(v.to_le_bytes());
    }
    #[inline]
    fn u64(&mut self, v: u64) {
        self.bytes(v.to_le_bytes());
    }
    #[inline]
    fn f64s(&mut self, v: &[f64]) {
        for x in v {
            self.bytes(x.to_bits().to_le_bytes());
        }
    }
    fn counts(&mut self, c: ChannelCounts) {
        self.u16(c.n_y);
        self.u16(c.n_z);
        self.u16(c.n_r);
        self.u16(c.n_u);
    }
}

/// Encodes a measurement entry (`Handle` with its receive time, or `Observe` with 0).
pub fn encode_measurement(
    layout: &RecordLayout,
    kind: EntryKind,
    index: u64,
    m: &Measurement,
    t_recv_ns: u64,
    buf: &mut [u8],
) -> usize {
    let (ny, nz, nr, nu) = layout.channels();
    let mut p = Put { buf, at: 0 };
    p.u8(kind as u8);
    p.u64(index);
    p.u64(t_recv_ns);
    p.u32(m.contract_version);
    p.u32(m.flags);
    p.u64(m.seq);
    p.u64(m.t_sample_ns);
    p.u64(m.period_ns);
    p.u64(m.deadline_ns);
    p.counts(m.counts);
    p.f64s(&m.y[..ny]);
    p.f64s(&m.z[..nz]);
    p.f64s(&m.r[..nr]);
    p.f64s(&m.u_applied[..nu]);
    p.at
}

/// Encodes an entry without a body (`NewPeer`, `End`) or with one time (`WentSilent`).
pub fn encode_marker(kind: EntryKind, index: u64, time: Option<u64>, buf: &mut [u8]) -> usize {
    let mut p = Put { buf, at: 0 };
    p.u8(kind as u8);
    p.u64(index);
    if let Some(t) = time {
        p.u64(t);
    }
    p.at
}

/// Encodes an `Operator` entry.
pub fn encode_operator(
    index: u64,
    request_id: u64,
    command: u32,
    tunable: u32,
    value: f64,
    buf: &mut [u8],
) -> usize {
    let mut p = Put { buf, at: 0 };
    p.u8(EntryKind::Operator as u8);
    p.u64(index);
    p.u64(request_id);
    p.u32(command);
    p.u32(tunable);
    p.f64s(&[value]);
    p.at
}

/// Encodes a `Publish` entry.
pub fn encode_publish(
    layout: &RecordLayout,
    index: u64,
    act: &Actuation,
    ok: bool,
    t_pub_ns: u64,
    buf: &mut [u8],
) -> usize {
    let (_, _, _, nu) = layout.channels();
    let mut p = Put { buf, at: 0 };
    p.u8(EntryKind::Publish as u8);
    p.u64(index);
    p.u8(u8::from(ok));
    p.u64(t_pub_ns);
    p.u32(act.contract_version);
    p.u32(act.status);
    p.u64(act.seq);
    p.u64(act.reply_to);
    p.u64(act.t_sample_ns);
    p.u64(act.compute_ns);
    p.counts(act.counts);
    p.u32(act.timing);
    p.u32(act.plan_len);
    p.f64s(&act.u[..nu]);
    for row in act.plan.iter().take(layout.plan_length) {
        p.f64s(&row[..nu]);
    }
    p.at
}

/// A little-endian reader over a whole entry (its length checked by the caller).
struct Get<'a> {
    buf: &'a [u8],
    at: usize,
}

impl Get<'_> {
    fn bytes<const N: usize>(&mut self) -> [u8; N] {
        let mut b = [0u8; N];
        if let Some(src) = self.buf.get(self.at..self.at + N) {
            b.copy_from_slice(src);
        }
        self.at += N;
        b
    }
    fn u8(&mut self) -> u8 {
        self.bytes::<1>()[0]
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.bytes())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.bytes())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.bytes())
    }
    fn f64s(&mut self, out: &mut [f64]) {
        for x in out {
            *x = f64::from_bits(self.u64());
        }
    }
    fn counts(&mut self) -> ChannelCounts {
        ChannelCounts {
            n_y: self.u16(),
            n_z: self.u16(),
            n_r: self.u16(),
            n_u: self.u16(),
        }
    }
}

/// Decodes a whole entry of `kind` (`bytes` is exactly `layout.entry_bytes(kind)` long, its
/// first byte the kind); returns its index and the entry.
pub fn decode(layout: &RecordLayout, kind: EntryKind, bytes: &[u8]) -> (u64, Entry) {
    let (ny, nz, nr, nu) = layout.channels();
    let mut g = Get { buf: bytes, at: 1 };
    let index = g.u64();
    let entry = match kind {
        EntryKind::Handle | EntryKind::Observe => {
            let t_recv_ns = g.u64();
            let mut m = Measurement::zeroed(layout.counts);
            m.contract_version = g.u32();
            m.flags = g.u32();
            m.seq = g.u64();
            m.t_sample_ns = g.u64();
            m.period_ns = g.u64();
            m.deadline_ns = g.u64();
            m.counts = g.counts();
            g.f64s(&mut m.y[..ny]);
            g.f64s(&mut m.z[..nz]);
            g.f64s(&mut m.r[..nr]);
            g.f64s(&mut m.u_applied[..nu]);
            if kind == EntryKind::Handle {
                Entry::Handle { m, t_recv_ns }
            } else {
                Entry::Observe { m }
            }
        }
        EntryKind::NewPeer => Entry::NewPeer,
        EntryKind::End => Entry::End,
        EntryKind::WentSilent => Entry::WentSilent { now_ns: g.u64() },
        EntryKind::Operator => {
            let request_id = g.u64();
            let command = g.u32();
            let index = g.u32();
            let mut value = [0.0];
            g.f64s(&mut value);
            Entry::Operator {
                request_id,
                command,
                index,
                value: value[0],
            }
        }
        EntryKind::Publish => {
            let ok = g.u8() != 0;
            let t_pub_ns = g.u64();
            let mut act = Actuation::zeroed(layout.counts);
            act.contract_version = g.u32();
            act.status = g.u32();
            act.seq = g.u64();
            act.reply_to = g.u64();
            act.t_sample_ns = g.u64();
            act.compute_ns = g.u64();
            act.counts = g.counts();
            act.timing = g.u32();
            act.plan_len = g.u32();
            g.f64s(&mut act.u[..nu]);
            for row in act.plan.iter_mut().take(layout.plan_length.min(MAX_PLAN)) {
                g.f64s(&mut row[..nu]);
            }
            Entry::Publish { act, ok, t_pub_ns }
        }
    };
    debug_assert_eq!(g.at, layout.entry_bytes(kind).max(ENTRY_HEAD_BYTES));
    (index, entry)
}
