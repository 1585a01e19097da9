//! The other tasks seen on the RT core: a scan of `/proc/[pid]/task/[tid]/stat` and what a
//! series of scans accumulates.
//!
//! A task's `stat` line is `tid (comm) state …`; counting from 1, field 3 is its state
//! (`R`: running or runnable), field 9 its flags (`PF_KTHREAD` = 0x0020_0000 marks a
//! kernel thread), fields 14–15 its user and system CPU time in `USER_HZ` ticks, and field
//! 39 `processor` the CPU it last ran on. `comm` may hold spaces and parentheses, so the
//! fields are counted from the last `)`.
//!
//! [`CoreTasks`] takes one scan after another. A task counts as seen on the core in a scan
//! when its `processor` is the core and it is runnable, or it gained CPU time since the
//! previous scan while it is last on the core; the ticks gained are added to it. The
//! excluded threads (the service's RT thread, the scanning thread) are never counted.
//! Memory is bounded: at most [`CoreTasks::capacity`] tasks are kept, the one with the
//! least CPU time making way for a newcomer with more; the totals over all tasks are kept
//! apart, so that nothing evicted is lost from them.

use serde::Serialize;
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

/// `PF_KTHREAD`: the task is a kernel thread.
const PF_KTHREAD: u64 = 0x0020_0000;

/// What one `stat` line says about a task.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TaskStat {
    /// Process (thread group) id.
    pub pid: u32,
    /// Thread id.
    pub tid: u32,
    /// Its name (`comm`).
    pub comm: String,
    /// Its state (`R`, `S`, `D`, …).
    pub state: char,
    /// A kernel thread (`PF_KTHREAD`).
    pub kernel_thread: bool,
    /// User plus system CPU time, `USER_HZ` ticks.
    pub ticks: u64,
    /// The CPU it last ran on.
    pub processor: usize,
}

/// Parses the `stat` line of thread `tid` of process `pid`; `None` when it does not parse.
pub fn parse_task_stat(pid: u32, text: &str) -> Option<TaskStat> {
    let open = text.find('(')?;
    let close = text.rfind(')')?;
    let tid: u32 = text[..open].trim().parse().ok()?;
    let comm = text.get(open + 1..close)?.to_string();
    // rest[0] is field 3.
    let rest: Vec<&str> = text[close + 1..].split_whitespace().collect();
    let field = |n: usize| rest.get(n - 3).copied();
    let state = field(3)?.chars().next()?;
    let flags: u64 = field(9)?.parse().ok()?;
    let utime: u64 = field(14)?.parse().ok()?;
    let stime: u64 = field(15)?.parse().ok()?;
    let processor: usize = field(39)?.parse().ok()?;
    Some(TaskStat {
        pid,
        tid,
        comm,
        state,
        kernel_thread: flags & PF_KTHREAD != 0,
        ticks: utime + stime,
        processor,
    })
}

/// Field 20 `num_threads` of a `stat` line.
pub fn num_threads(text: &str) -> Option<u64> {
    text[text.rfind(')')? + 1..]
        .split_whitespace()
        .nth(20 - 3)?
        .parse()
        .ok()
}

fn read_into(path: &Path, buf: &mut String) -> bool {
    buf.clear();
    std::fs::File::open(path)
        .and_then(|mut f| f.read_to_string(buf))
        .is_ok()
}

/// Reads every task of every process under `proc_dir` (`/proc`) into `out` (cleared
/// first). A process with one thread is read from its `/proc/[pid]/stat` (the same line as
/// its only task's), the others task by task. Tasks that end while being read, or whose
/// file does not parse, are skipped. Returns false when `proc_dir` cannot be listed.
pub fn scan_tasks(proc_dir: &Path, out: &mut Vec<TaskStat>) -> bool {
    out.clear();
    let Ok(procs) = std::fs::read_dir(proc_dir) else {
        return false;
    };
    let mut buf = String::with_capacity(512);
    for p in procs.flatten() {
        let Some(pid) = p.file_name().to_str().and_then(|n| n.parse::<u32>().ok()) else {
            continue;
        };
        let dir = p.path();
        if read_into(&dir.join("stat"), &mut buf) && num_threads(&buf) == Some(1) {
            out.extend(parse_task_stat(pid, &buf));
            continue;
        }
        let Ok(tasks) = std::fs::read_dir(dir.join("task")) else {
            continue;
        };
        for t in tasks.flatten() {
            if read_into(&t.path().join("stat"), &mut buf) {
                out.extend(parse_task_stat(pid, &buf));
            }
        }
    }
    true
}

/// A task seen on the RT core, and how much.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct CoreTask {
    /// Process id.
    pub pid: u32,
    /// Thread id.
    pub tid: u32,
    /// Its name when last seen.
    pub comm: String,
    /// A kernel thread (a per-CPU `ksoftirqd/N`, `kworker/N:M`, …).
    pub kernel_thread: bool,
    /// Scans in which it was seen on the core.
    pub samples: u64,
    /// CPU time gained while last on the core, `USER_HZ` ticks.
    pub ticks: u64,
}

impl CoreTask {
    fn weight(&self) -> (u64, u64) {
        (self.ticks, self.samples)
    }
}

/// What the scans saw on one core (see the module docs).
#[derive(Debug, Clone)]
pub struct CoreTasks {
    core: usize,
    keep: usize,
    exclude: Vec<u32>,
    prev: HashMap<u32, u64>,
    next: HashMap<u32, u64>,
    seen: Vec<CoreTask>,
    scans: u64,
    total_ticks: u64,
    user_ticks: u64,
    evicted: u64,
}

impl CoreTasks {
    /// Watches `core`, reporting the `keep` tasks with the most CPU time.
    pub fn new(core: usize, keep: usize) -> Self {
        let keep = keep.max(1);
        Self {
            core,
            keep,
            exclude: Vec::new(),
            prev: HashMap::new(),
            next: HashMap::new(),
            seen: Vec::with_capacity(2 * keep),
            scans: 0,
            total_ticks: 0,
            user_ticks: 0,
            evicted: 0,
        }
    }

    /// The core watched.
    pub fn core(&self) -> usize {
        self.core
    }

    /// Tasks kept at most (twice those reported).
    pub fn capacity(&self) -> usize {
        2 * self.keep
    }

    /// Never counts thread `tid` (the RT thread, the scanning thread).
    pub fn exclude(&mut self, tid: u32) {
        if !self.exclude.contains(&tid) {
            self.exclude.push(tid);
        }
    }

    /// Takes in one scan of every task.
    pub fn observe(&mut self, tasks: &[TaskStat]) {
        self.scans += 1;
        self.next.clear();
        for t in tasks {
            self.next.insert(t.tid, t.ticks);
            if self.exclude.contains(&t.tid) || t.processor != self.core {
                continue;
            }
            let gained = self
                .prev
                .get(&t.tid)
                .map_or(0, |p| t.ticks.saturating_sub(*p));
            if t.state != 'R' && gained == 0 {
                continue;
            }
            self.total_ticks += gained;
            if !t.kernel_thread {
                self.user_ticks += gained;
            }
            self.note(t, gained);
        }
        std::mem::swap(&mut self.prev, &mut self.next);
    }

    fn note(&mut self, t: &TaskStat, gained: u64) {
        if let Some(c) = self.seen.iter_mut().find(|c| c.tid == t.tid) {
            c.samples += 1;
            c.ticks += gained;
            if c.comm != t.comm {
                c.comm.clone_from(&t.comm);
            }
            return;
        }
        let new = CoreTask {
            pid: t.pid,
            tid: t.tid,
            comm: t.comm.clone(),
            kernel_thread: t.kernel_thread,
            samples: 1,
            ticks: gained,
        };
        if self.seen.len() < self.capacity() {
            self.seen.push(new);
            return;
        }
        self.evicted += 1;
        let weakest = self
            .seen
            .iter()
            .enumerate()
            .min_by_key(|(_, c)| c.weight())
            .map(|(i, _)| i);
        if let Some(i) = weakest.filter(|i| self.seen[*i].weight() < new.weight()) {
            self.seen[i] = new;
        }
    }

    /// Scans taken in.
    pub fn scans(&self) -> u64 {
        self.scans
    }

    /// CPU ticks all counted tasks gained on the core, and those of user-space tasks
    /// (evicted ones included).
    pub fn total_ticks(&self) -> (u64, u64) {
        (self.total_ticks, self.user_ticks)
    }

    /// Sightings that found the list full (the newcomer or the weakest kept task was
    /// dropped).
    pub fn evicted(&self) -> u64 {
        self.evicted
    }

    /// The tasks with the most CPU time on the core (then the most sightings), at most
    /// `keep`.
    pub fn top(&self) -> Vec<CoreTask> {
        let mut v = self.seen.clone();
        v.sort_by(|a, b| b.weight().cmp(&a.weight()).then(a.tid.cmp(&b.tid)));
        v.truncate(self.keep);
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `stat` line with the fields the parser reads.
    /// `line` with field `n` (counted from 1, `comm` being field 2) set to `value`.
    fn with_field(line: &str, n: usize, value: &str) -> String {
        let close = line.rfind(')').unwrap();
        let mut rest: Vec<&str> = line[close + 1..].split_whitespace().collect();
        rest[n - 3] = value;
        format!("{} {}\n", &line[..=close], rest.join(" "))
    }

    fn stat_line(
        tid: u32,
        comm: &str,
        state: char,
        kthread: bool,
        ticks: u64,
        cpu: usize,
    ) -> String {
        let mut f: Vec<String> = (3..=52).map(|_| "0".to_string()).collect();
        f[0] = state.to_string();
        f[9 - 3] = if kthread { "2129984" } else { "4194560" }.into();
        f[14 - 3] = (ticks / 2).to_string();
        f[15 - 3] = (ticks - ticks / 2).to_string();
        f[39 - 3] = cpu.to_string();
        f[20 - 3] = "1".into();
        format!("{tid} ({comm}) {}\n", f.join(" "))
    }

    fn task(tid: u32, state: char, ticks: u64, cpu: usize) -> TaskStat {
        parse_task_stat(
            tid,
            &stat_line(tid, &format!("t{tid}"), state, false, ticks, cpu),
        )
        .unwrap()
    }

    #[test]
    fn a_stat_line_parses_from_the_last_parenthesis() {
        let t = parse_task_stat(7, &stat_line(9, "we (ird) name", 'R', false, 41, 1)).unwrap();
        assert_eq!(
            t,
            TaskStat {
                pid: 7,
                tid: 9,
                comm: "we (ird) name".into(),
                state: 'R',
                kernel_thread: false,
                ticks: 41,
                processor: 1,
            }
        );
        let k = parse_task_stat(3, &stat_line(3, "ksoftirqd/1", 'S', true, 0, 1)).unwrap();
        assert!(k.kernel_thread);
        assert_eq!(parse_task_stat(1, "1 (init) S 0 1"), None);
        assert_eq!(parse_task_stat(1, "garbage"), None);
    }

    #[test]
    fn runnable_tasks_and_cpu_gained_on_the_core_are_counted_others_are_not() {
        let mut c = CoreTasks::new(1, 4);
        c.exclude(100); // the RT thread
        // Scan 1: baselines.
        c.observe(&[
            task(100, 'R', 1000, 1),
            task(200, 'R', 50, 1), // a hog, runnable on the core
            task(300, 'S', 10, 1), // asleep, last on the core
            task(400, 'R', 70, 0), // on the other core
        ]);
        // Scan 2: the hog gained 9 ticks, the sleeper 2, the other-core task 30.
        c.observe(&[
            task(100, 'R', 1010, 1),
            task(200, 'R', 59, 1),
            task(300, 'S', 12, 1),
            task(400, 'R', 100, 0),
            task(500, 'S', 5, 1), // new and asleep: not seen
        ]);
        let top = c.top();
        let seen: Vec<(u32, u64, u64)> = top.iter().map(|t| (t.tid, t.samples, t.ticks)).collect();
        assert_eq!(seen, vec![(200, 2, 9), (300, 1, 2)]);
        assert_eq!(c.scans(), 2);
        assert_eq!(c.total_ticks(), (11, 11));
    }

    #[test]
    fn memory_is_bounded_and_keeps_the_tasks_with_the_most_cpu() {
        let mut c = CoreTasks::new(0, 2);
        let mut scan = |ticks: &dyn Fn(u32) -> u64| {
            let v: Vec<TaskStat> = (1..=10).map(|tid| task(tid, 'R', ticks(tid), 0)).collect();
            c.observe(&v);
        };
        scan(&|_| 0);
        scan(&|tid| tid as u64 * 10);
        let top = c.top();
        assert_eq!(top.len(), 2);
        assert!(c.seen.len() <= c.capacity());
        assert_eq!(
            top.iter().map(|t| t.tid).collect::<Vec<_>>(),
            vec![10, 9],
            "{top:?}"
        );
        // Totals count every task, kept or not.
        assert_eq!(c.total_ticks().0, (1..=10).map(|t| t * 10).sum::<u64>());
        assert!(c.evicted() > 0);
    }

    #[test]
    fn a_made_up_proc_is_scanned() {
        let root = std::env::temp_dir().join(format!("core-tasks-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        for (pid, tid, cpu) in [(10, 10, 1), (10, 11, 0), (20, 20, 1)] {
            let d = root.join(format!("{pid}/task/{tid}"));
            std::fs::create_dir_all(&d).unwrap();
            std::fs::write(d.join("stat"), stat_line(tid, "x", 'R', false, 3, cpu)).unwrap();
        }
        // Process 10 has two threads (read task by task), 20 one (read from its stat).
        let two = with_field(&stat_line(10, "x", 'R', false, 6, 1), 20, "2");
        assert_eq!(num_threads(&two), Some(2), "{two}");
        std::fs::write(root.join("10/stat"), two).unwrap();
        std::fs::write(root.join("20/stat"), stat_line(20, "x", 'R', false, 3, 1)).unwrap();
        std::fs::create_dir_all(root.join("sys")).unwrap();
        let mut out = Vec::new();
        assert!(scan_tasks(&root, &mut out));
        out.sort_by_key(|t| t.tid);
        assert_eq!(
            out.iter()
                .map(|t| (t.pid, t.tid, t.processor))
                .collect::<Vec<_>>(),
            vec![(10, 10, 1), (10, 11, 0), (20, 20, 1)]
        );
        assert!(!scan_tasks(&root.join("absent"), &mut out));
        let _ = std::fs::remove_dir_all(&root);
    }
}
