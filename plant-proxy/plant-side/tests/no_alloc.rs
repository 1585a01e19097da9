//! The plant side's per-sample path allocates nothing of its own: `publish` and `take` (in
//! lockstep and with `Wait::Until`) run under the RT-aware allocator of `ipc_types::rt_alloc`
//! against a service thread over real iceoryx2 ports. Nothing goes to the system allocator,
//! and the pool serves exactly one block per published sample (iceoryx2 0.10's loan state,
//! see `ipc_types::rt_alloc`); every input is the service's answer for its own sample.

use ipc_types::ports::{ConnectOptions, ContractInfo, ServicePorts, Side};
use ipc_types::rt_alloc::{RtAwareAllocator, enter_rt_thread, thread_stats};
use ipc_types::{Actuation, ChannelCounts, Timing, measurement_flags};
use plant_side::{InputKind, Mode, PlantPolicy, PlantSide, PlantSideOptions, Wait};
use std::time::Duration;

#[global_allocator]
static ALLOCATOR: RtAwareAllocator = RtAwareAllocator;

/// A compute-first service thread: answers measurement `k` with `u = k`, until the last.
fn service(rig: String, counts: ChannelCounts) -> std::thread::JoinHandle<u64> {
    std::thread::spawn(move || {
        let own =
            ContractInfo::new(Side::Service, counts, 1_000_000).with_timing(Timing::ComputeFirst);
        let opts = ConnectOptions::new(Duration::from_secs(20)).with_listener(true);
        let ports: ServicePorts =
            ipc_types::ports::connect(&rig, own, "no-alloc-service", opts).expect("connect");
        let mut answered = 0;
        loop {
            let Ok(Some(m)) = ports.subscriber.receive() else {
                if let Some(l) = &ports.listener {
                    let _ = l.timed_wait(|_| {}, Duration::from_millis(5));
                }
                continue;
            };
            let mut a = Actuation::zeroed(counts);
            (a.seq, a.reply_to, a.timing) = (m.seq, m.seq, Timing::ComputeFirst.wire());
            a.u[0] = m.seq as f64;
            ports.publisher.send_copy(a).expect("send");
            let _ = ports.notifier.notify();
            answered += 1;
            if m.flags & measurement_flags::LAST_SAMPLE != 0 {
                return answered;
            }
        }
    })
}

fn steady_state_allocations(rig: &str, wait: impl Fn(u64) -> Wait) {
    let counts = ChannelCounts::new(1, 1, 0, 1).unwrap();
    let svc = service(rig.to_string(), counts);
    let mut policy = PlantPolicy::new(1);
    policy.mode = Mode::Lockstep;
    let mut side = PlantSide::connect(
        rig,
        counts,
        1_000_000,
        policy,
        PlantSideOptions::new("no-alloc"),
    )
    .expect("connect");
    let (warm, steady) = (200, 2000);
    let step = |k: u64, side: &mut PlantSide<'_>| {
        let last = if k + 1 == warm + steady {
            measurement_flags::LAST_SAMPLE
        } else {
            0
        };
        side.publish(
            k,
            ipc_types::clock::monotonic_ns(),
            [&[1.0], &[1.0], &[]],
            last,
        )
        .expect("publish");
        side.take(k, wait(k)).expect("take").expect("not stopped")
    };
    for k in 0..warm {
        step(k, &mut side);
    }
    enter_rt_thread(64);
    let before = thread_stats();
    let mut wrong = None;
    for k in warm..warm + steady {
        let input = step(k, &mut side);
        if (input.kind, input.u[0]) != (InputKind::Answered, k as f64) && wrong.is_none() {
            wrong = Some((k, input.kind, input.u[0]));
        }
    }
    let allocations = thread_stats().since(&before);
    assert_eq!(
        wrong, None,
        "an input that is not the answer for its sample"
    );
    assert!(
        allocations.installed && allocations.counted,
        "{allocations:?}"
    );
    assert_eq!(
        allocations.system_on_rt_thread, 0,
        "system allocations in {steady} steady-state samples"
    );
    assert_eq!(
        allocations.pool_served, steady,
        "pool blocks: one per published sample (iceoryx2's loan state), nothing else"
    );
    assert_eq!(svc.join().expect("service thread"), warm + steady);
    let report = side.finish();
    assert_eq!(report.actuations_applied, warm + steady);
    assert_eq!(report.round_trip.expect("timed").samples, warm + steady);
}

#[test]
fn publish_and_take_in_lockstep_allocate_nothing_from_the_system() {
    steady_state_allocations(&format!("no-alloc-ls-{}", std::process::id()), |_| {
        Wait::Lockstep
    });
}

#[test]
fn publish_and_take_until_the_answer_allocate_nothing_from_the_system() {
    steady_state_allocations(&format!("no-alloc-until-{}", std::process::id()), |_| {
        Wait::Until(ipc_types::clock::monotonic_ns() + 1_000_000_000)
    });
}
