/*
 * adaptive_rig.h -- the C interface of the adaptive-rig contract (library adaptive_rig,
 * crate ipc-types/c): the plant side for DAQ drivers written in C or C++, and a minimal
 * controller side.
 *
 * Build the library with `cargo build --release -p adaptive-rig-c`; it gives
 * target/release/libadaptive_rig.a and target/release/libadaptive_rig.so. Link:
 *   cc  -I ipc-types/include my_daq.c   target/release/libadaptive_rig.a -lgcc_s -lutil -lrt -lpthread -lm -ldl -lc
 *   c++ -I ipc-types/include my_daq.cpp target/release/libadaptive_rig.a -lgcc_s -lutil -lrt -lpthread -lm -ldl -lc
 * or -L target/release -ladaptive_rig -Wl,-rpath,<dir> for the shared library.
 *
 * A plant's period k (see ipc-types/c/README.md):
 *   t_k = sample instant (ar_monotonic_ns(), or the DAQ's clock on CLOCK_MONOTONIC)
 *   read the ADC: y, z, r
 *   ar_plant_publish(plant, k, t_k, y, z, r, last ? AR_MEAS_LAST_SAMPLE : 0, NULL)
 *   ar_plant_take(plant, k, AR_WAIT_LOCKSTEP, 0, u, &kind)            (lockstep)
 *   ar_plant_take(plant, k, AR_WAIT_AT, t_k + deadline_offset, u, &kind)  (real time)
 *   write u to the DAC
 *
 * Errors: every function that can fail returns an ar_status_t: AR_OK (0), AR_STOPPED (1: a
 * wait ended by ar_request_stop), or a negative AR_ERR_* code; ar_last_error() gives the
 * message of the calling thread's last failure, the text the Rust processes print (a
 * contract mismatch names each difference). No panic crosses the boundary (AR_ERR_PANIC).
 *
 * Thread safety: a handle (ar_plant_t*, ar_controller_t*) is used by one thread at a time;
 * it may move between threads between calls. Different handles are independent.
 * ar_last_error() is per thread. ar_request_stop() is async-signal-safe.
 *
 * The Rust tests check this header against the library: every exported ar_ function is
 * declared here and every one declared is exported, the constants match, and the sizes and
 * offsets of the structs below match the Rust layout (in C and in C++).
 */
#ifndef ADAPTIVE_RIG_H
#define ADAPTIVE_RIG_H

#include "adaptive_rig_contract.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- return codes ---- */

typedef int32_t ar_status_t;

#define AR_OK 0
/* a wait (open, lockstep take, receive) ended because ar_request_stop() was called */
#define AR_STOPPED 1
/* a null pointer, a count past the capacity, bad UTF-8, a value out of range: the message names the argument */
#define AR_ERR_INVALID_ARGUMENT (-1)
/* iceoryx2 failed while connecting */
#define AR_ERR_CONNECT (-2)
/* the peer states another contract (version, counts, period, timing): the message names each difference */
#define AR_ERR_MISMATCH (-3)
/* the peer did not appear, or no sample came, in time */
#define AR_ERR_TIMEOUT (-4)
/* lockstep: no service answered for peer_timeout_s after the watchdog tripped */
#define AR_ERR_GAVE_UP (-5)
/* a send or receive failed during the run */
#define AR_ERR_IO (-6)
/* a panic inside the library was caught: only close the handle concerned */
#define AR_ERR_PANIC (-7)
/* another live process holds this side of the rig or a port slot of the contract */
#define AR_ERR_IN_USE (-8)
/* iceoryx2's shared-memory files belong to another user */
#define AR_ERR_PERMISSION (-9)
/* the caller's buffer is too small; the length needed was written */
#define AR_ERR_BUFFER_TOO_SMALL (-10)

/* The message of the calling thread's last failed call ("" when none). Never NULL. Valid
 * until the next ar_ call on the same thread: copy it to keep it. */
const char* ar_last_error(void);

/* The name of a status code ("AR_ERR_MISMATCH"), or "AR_UNKNOWN_STATUS". Static; never NULL. */
const char* ar_status_name(ar_status_t status);

/* ---- clock and stop ---- */

/* CLOCK_MONOTONIC in nanoseconds: the time base of t_sample_ns and of AR_WAIT_AT/UNTIL. */
uint64_t ar_monotonic_ns(void);

/* Sleeps until the absolute CLOCK_MONOTONIC time t_ns (returns at once when it is past). */
void ar_sleep_until_ns(uint64_t t_ns);

/* Ends every wait of the process (open, lockstep take, receive) with AR_STOPPED, now and
 * until ar_clear_stop(). Async-signal-safe: call it from a SIGINT/SIGTERM handler. */
void ar_request_stop(void);

/* Withdraws a stop request. */
void ar_clear_stop(void);

/* 1 when a stop was requested, else 0. */
int32_t ar_stop_requested(void);

/* ---- plant side ---- */

/* config->mode */
#define AR_MODE_REAL_TIME 0
#define AR_MODE_LOCKSTEP 1

/* config->late_policy (and config->plan_fallback: HOLD or SAFE) */
#define AR_LATE_HOLD 0
#define AR_LATE_SAFE 1
#define AR_LATE_PLAN 2

/* ar_plant_take's wait */
typedef int32_t ar_wait_t;
/* decide from what has arrived */
#define AR_WAIT_NOW 0
/* sleep until t_ns, then decide from what has arrived */
#define AR_WAIT_AT 1
/* decide as soon as the answer is there, at the latest at t_ns */
#define AR_WAIT_UNTIL 2
/* wait for the service's answer to sample k (at most lockstep_timeout_s); t_ns unused */
#define AR_WAIT_LOCKSTEP 3

/* where the input of a sample comes from */
typedef int32_t ar_input_kind_t;
/* the service's actuation for the sample */
#define AR_INPUT_ANSWERED 0
/* a miss covered by the newest plan's entry */
#define AR_INPUT_PLAN 1
/* a miss: the previous input, held */
#define AR_INPUT_HELD 2
/* a miss: the safe input */
#define AR_INPUT_SAFE 3
/* the watchdog holds the safe output (engage a hardware safe state here) */
#define AR_INPUT_WATCHDOG_SAFE 4

/* How a plant connects and runs. Fill it with ar_plant_config_init(), then set rig,
 * counts, period_ns and what differs from the defaults. */
typedef struct ar_plant_config {
    const char* rig;             /* rig name: 1-64 of [A-Za-z0-9_-] */
    ar_channel_counts_t counts;  /* the service must state the same */
    uint64_t period_ns;          /* the service must state the same */
    int32_t mode;                /* AR_MODE_REAL_TIME (default) or AR_MODE_LOCKSTEP */
    int32_t late_policy;         /* AR_LATE_HOLD (default), AR_LATE_SAFE, AR_LATE_PLAN */
    int32_t plan_fallback;       /* with AR_LATE_PLAN: AR_LATE_HOLD (default) or AR_LATE_SAFE */
    int32_t verbose;             /* non-zero: progress and events on stderr */
    double deadline;             /* real time: apply at t_k + deadline*T, in [0, 1] (default 0.8) */
    const double* safe_input;    /* counts.n_u values, or NULL for zeros; copied */
    uint64_t watchdog_periods;   /* consecutive misses that trip the watchdog (default 100) */
    double lockstep_timeout_s;   /* lockstep: wait for each answer at most this (default 1) */
    double peer_timeout_s;       /* wait for the service at open, and after a trip (default 30) */
    const char* label;           /* prefix of messages on stderr, or NULL for "c-plant" */
} ar_plant_config_t;

#define AR_PLANT_CONFIG_SIZE 88

/* One connected plant side; opaque. */
typedef struct ar_plant ar_plant_t;

/* The counters of a plant so far (plant-side's PlantReport).
 * misses = plan_entries_applied + misses_held_or_safe. */
typedef struct ar_plant_report {
    uint64_t samples;                    /* samples published */
    uint64_t actuations_applied;         /* valid answers applied by their application instant */
    uint64_t misses;                     /* samples without a valid answer in time */
    uint64_t plan_entries_applied;       /* misses covered by a plan's entry */
    uint64_t misses_held_or_safe;        /* misses applied as a held or safe output */
    uint64_t misses_before_first_answer; /* of those, before the first answer */
    uint64_t late_discarded;             /* answers that came after their sample was decided */
    uint64_t invalid_discarded;          /* answers refused as invalid */
    uint64_t ahead_dropped;              /* answers received ahead and dropped for room */
    uint64_t foreign_discarded;          /* answers refused: not from the pinned service */
    uint64_t new_services;               /* times a new service replaced the pinned one */
    uint64_t watchdog_trips;
    uint64_t watchdog_recoveries;
    uint64_t safe_output_samples;        /* samples spent in the safe output */
    uint64_t stalls_injected;            /* samples published with AR_MEAS_INJECTED_STALL */
    uint64_t stall_acks;                 /* stall acknowledgements received */
    double wall_time_s;                  /* seconds from ar_plant_open to the latest input taken */
    uint32_t service_pid;                /* pid of the pinned service, 0 when unknown */
    uint32_t gave_up;                    /* 1 once ar_plant_take returned AR_ERR_GAVE_UP */
} ar_plant_report_t;

#define AR_PLANT_REPORT_SIZE 144

/* Fills *config with the defaults (those of plant-proxy's [proxy] table); rig and label
 * NULL, counts and period 0. */
ar_status_t ar_plant_config_init(ar_plant_config_t* config);

/* Connects to the service of config->rig as its plant; the handle goes to *out (only on
 * success). Waits up to config->peer_timeout_s for the service. AR_ERR_MISMATCH when the
 * service states another contract (ar_last_error() names each difference), AR_ERR_IN_USE
 * when the rig already has a plant, AR_ERR_TIMEOUT when no service came, AR_STOPPED on
 * ar_request_stop(), AR_ERR_INVALID_ARGUMENT naming a bad field. */
ar_status_t ar_plant_open(const ar_plant_config_t* config, ar_plant_t** out);

/* Publishes the measurement of sample k taken at t_sample_ns (CLOCK_MONOTONIC): counts.n_y
 * values at y, n_z at z, n_r at r (NULL allowed for a count of 0). extra_flags:
 * AR_MEAS_LAST_SAMPLE on the last sample of a run (AR_MEAS_INJECTED_STALL in lockstep
 * tests); the other flags are the plant side's. The flags published go to *flags_out
 * unless it is NULL. */
ar_status_t ar_plant_publish(ar_plant_t* plant, uint64_t k, uint64_t t_sample_ns,
                             const double* y, const double* z, const double* r,
                             uint32_t extra_flags, uint32_t* flags_out);

/* Decides the input of sample k when wait says (AR_WAIT_NOW, AR_WAIT_AT t_ns,
 * AR_WAIT_UNTIL t_ns, AR_WAIT_LOCKSTEP) and writes counts.n_u values to u_out, its kind to
 * *kind_out (unless NULL). Once per sample, k increasing. On a miss the input is the late
 * policy's (held, safe, a plan's entry) and the next measurement says so. AR_STOPPED:
 * ar_request_stop() while unanswered (nothing written); AR_ERR_GAVE_UP: lockstep, no
 * service answered for peer_timeout_s after the watchdog tripped (close the handle). */
ar_status_t ar_plant_take(ar_plant_t* plant, uint64_t k, ar_wait_t wait, uint64_t t_ns,
                          double* u_out, ar_input_kind_t* kind_out);

/* The deadline offset deadline*T of the measurements in ns (0 in lockstep): the
 * application instant of sample k is t_k + *out. */
ar_status_t ar_plant_deadline_offset_ns(const ar_plant_t* plant, uint64_t* out);

/* The counters so far. They change only with ar_plant_publish and ar_plant_take. */
ar_status_t ar_plant_report(const ar_plant_t* plant, ar_plant_report_t* out);

/* The report so far as JSON (plant-proxy's plant-report.json fields), NUL-terminated, into
 * buf of capacity bytes; *len_out (unless NULL) = its length without the NUL.
 * AR_ERR_BUFFER_TOO_SMALL when it does not fit (buf untouched); buf may be NULL with
 * capacity 0 to ask for the length (the report does not change until the next publish or
 * take, so a buffer of that length plus one then fits). */
ar_status_t ar_plant_report_json(const ar_plant_t* plant, char* buf, size_t capacity,
                                 size_t* len_out);

/* Disconnects and frees the handle (NULL is ignored). */
ar_status_t ar_plant_close(ar_plant_t* plant);

/* ---- controller side (a controller written in C; the Rust service is the product's) ---- */

/* One connected service side; opaque. */
typedef struct ar_controller ar_controller_t;

/* Connects to the plant of rig as its service: counts, period_ns, answering with timing
 * (AR_TIMING_*); waits up to peer_timeout_s for the plant. Errors as ar_plant_open. */
ar_status_t ar_controller_open(const char* rig, ar_channel_counts_t counts, uint64_t period_ns,
                               uint32_t timing, double peer_timeout_s, ar_controller_t** out);

/* The oldest pending measurement of the pinned plant into *out, waiting up to timeout_ns
 * (0: no wait). Other publishers' samples are refused. AR_ERR_TIMEOUT when none came. */
ar_status_t ar_controller_receive(ar_controller_t* ctrl, ar_measurement_t* out,
                                  uint64_t timeout_ns);

/* An empty actuation of this controller: version, counts and timing set, the rest zero. */
ar_status_t ar_controller_actuation_init(const ar_controller_t* ctrl, ar_actuation_t* out);

/* Publishes *act (t_publish_ns stamped now) and notifies the plant. Set seq (the sample the
 * input is for), reply_to, t_sample_ns (echoed), status and u. */
ar_status_t ar_controller_send(ar_controller_t* ctrl, const ar_actuation_t* act);

/* Disconnects and frees the handle (NULL is ignored). */
ar_status_t ar_controller_close(ar_controller_t* ctrl);

#ifdef __cplusplus
} /* extern "C" */
#endif

#if defined(__cplusplus) && __cplusplus >= 201103L
static_assert(sizeof(ar_plant_config_t) == AR_PLANT_CONFIG_SIZE, "ar_plant_config_t size");
static_assert(sizeof(ar_plant_report_t) == AR_PLANT_REPORT_SIZE, "ar_plant_report_t size");
#elif defined(__STDC_VERSION__) && __STDC_VERSION__ >= 201112L
_Static_assert(sizeof(ar_plant_config_t) == AR_PLANT_CONFIG_SIZE, "ar_plant_config_t size");
_Static_assert(sizeof(ar_plant_report_t) == AR_PLANT_REPORT_SIZE, "ar_plant_report_t size");
#endif

#endif /* ADAPTIVE_RIG_H */
