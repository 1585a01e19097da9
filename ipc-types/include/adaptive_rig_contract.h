/*
 * adaptive_rig_contract.h -- the wire contract between a plant process (simulation or
 * DAQ I/O) and the adaptive control service, for processes written in C or C++ against
 * iceoryx2's C/C++ API.
 *
 * This header mirrors ipc-types/src/lib.rs. The Rust test suite reads the numbers below
 * and checks them against the Rust layout; the _Static_asserts check them against your
 * C compiler's layout. Change both together and bump AR_CONTRACT_VERSION.
 *
 * Services (N = the rig name):
 *   "adaptive-rig/N/measurement"  publish-subscribe, payload ar_measurement_t,
 *                                 type name AR_MEASUREMENT_TYPE_NAME, created by the plant
 *   "adaptive-rig/N/actuation"    publish-subscribe, payload ar_actuation_t,
 *                                 type name AR_ACTUATION_TYPE_NAME, created by the service
 *   "adaptive-rig/N/measurement"  event, notified by the plant after each measurement
 *   "adaptive-rig/N/actuation"    event, notified by the service after each actuation
 * The creator of each publish-subscribe service defines the attributes
 *   "contract-version", "n-y", "n-z", "n-r", "n-u", "period-ns", "role"
 * as decimal strings ("role" is "plant" or "service"), and "timing": the service's timing
 * ("compute-first", "answer-first" or "send-ahead") or, for the plant, when it applies an
 * input ("at-sample", "at-deadline" or "lockstep"); the opener compares them with its own.
 * A plant that applies at the sample instant needs a service that sends ahead.
 * Timestamps are CLOCK_MONOTONIC in nanoseconds.
 */
#ifndef ADAPTIVE_RIG_CONTRACT_H
#define ADAPTIVE_RIG_CONTRACT_H

#include <stddef.h>
#include <stdint.h>

#define AR_CONTRACT_VERSION 3
#define AR_MAX_Y 16
#define AR_MAX_Z 16
#define AR_MAX_R 16
#define AR_MAX_U 8
#define AR_MAX_PLAN 64

#define AR_MEASUREMENT_TYPE_NAME "adaptive_rig::Measurement.v3"
#define AR_ACTUATION_TYPE_NAME "adaptive_rig::Actuation.v3"

/* Measurement flags */
#define AR_MEAS_LOCKSTEP 0x1u
#define AR_MEAS_PLANT_SAFE_OUTPUT 0x2u
#define AR_MEAS_PREVIOUS_ACTUATION_MISSED 0x4u
#define AR_MEAS_LAST_SAMPLE 0x8u
/* u_applied holds the input applied after sample k-1 */
#define AR_MEAS_U_APPLIED 0x10u
/* the previous actuation missed its deadline; the plant applied the entry of the latest plan */
#define AR_MEAS_PLAN_APPLIED 0x20u
/* lockstep only: an injected stall of the service; it observes the sample and acknowledges it */
#define AR_MEAS_INJECTED_STALL 0x40u

/* Actuation status bits */
#define AR_ACT_OK 0x0u
#define AR_ACT_SAFE_STATE 0x1u
#define AR_ACT_MEASUREMENT_REJECTED 0x2u
#define AR_ACT_SATURATED 0x4u
#define AR_ACT_STARTING 0x8u
#define AR_ACT_CONTROLLER_FAULT 0x10u
#define AR_ACT_OPEN_LOOP 0x20u
/* the controller could not compute its law (e.g. an infeasible MPC problem); u is its fallback */
#define AR_ACT_FALLBACK 0x40u
/* acknowledges a sample flagged AR_MEAS_INJECTED_STALL; u and the plan are not inputs */
#define AR_ACT_STALL_ACK 0x80u

/* ar_actuation_t.timing: when the service answers.
 * compute-first: u_k computed from y_k, then published as seq k;
 * answer-first: u_k prepared from the data up to k-1, published on receipt of sample k;
 * send-ahead: u_{k+1} published as seq k+1 as soon as y_k is taken in. */
#define AR_TIMING_COMPUTE_FIRST 0x0u
#define AR_TIMING_ANSWER_FIRST 0x1u
#define AR_TIMING_SEND_AHEAD 0x2u

typedef struct ar_channel_counts {
    uint16_t n_y;
    uint16_t n_z;
    uint16_t n_r;
    uint16_t n_u;
} ar_channel_counts_t;

#define AR_CHANNEL_COUNTS_SIZE 8
#define AR_CHANNEL_COUNTS_OFFSET_N_Y 0
#define AR_CHANNEL_COUNTS_OFFSET_N_Z 2
#define AR_CHANNEL_COUNTS_OFFSET_N_R 4
#define AR_CHANNEL_COUNTS_OFFSET_N_U 6

typedef struct ar_measurement {
    uint32_t contract_version;
    uint32_t flags;
    uint64_t seq;
    uint64_t t_sample_ns;
    uint64_t period_ns;
    uint64_t deadline_ns; /* the input for seq is applied at t_sample_ns + deadline_ns (0: at the sample) */
    ar_channel_counts_t counts;
    double y[AR_MAX_Y];
    double z[AR_MAX_Z];
    double r[AR_MAX_R];
    double u_applied[AR_MAX_U]; /* input applied after sample k-1; valid with AR_MEAS_U_APPLIED */
} ar_measurement_t;

#define AR_MEASUREMENT_SIZE 496
#define AR_MEASUREMENT_ALIGN 8
#define AR_MEASUREMENT_OFFSET_CONTRACT_VERSION 0
#define AR_MEASUREMENT_OFFSET_FLAGS 4
#define AR_MEASUREMENT_OFFSET_SEQ 8
#define AR_MEASUREMENT_OFFSET_T_SAMPLE_NS 16
#define AR_MEASUREMENT_OFFSET_PERIOD_NS 24
#define AR_MEASUREMENT_OFFSET_DEADLINE_NS 32
#define AR_MEASUREMENT_OFFSET_COUNTS 40
#define AR_MEASUREMENT_OFFSET_Y 48
#define AR_MEASUREMENT_OFFSET_Z 176
#define AR_MEASUREMENT_OFFSET_R 304
#define AR_MEASUREMENT_OFFSET_U_APPLIED 432

typedef struct ar_actuation {
    uint32_t contract_version;
    uint32_t status;
    uint64_t seq;         /* the sample whose period u is for */
    uint64_t reply_to;    /* the measurement whose receipt this answers (seq, or seq-1 sent ahead) */
    uint64_t t_sample_ns; /* t_sample_ns of reply_to, echoed */
    uint64_t t_publish_ns;
    uint64_t compute_ns;
    ar_channel_counts_t counts;
    uint32_t timing;      /* AR_TIMING_* */
    uint32_t plan_len;    /* valid entries of plan */
    double u[AR_MAX_U];
    double plan[AR_MAX_PLAN][AR_MAX_U]; /* plan[j]: the expected input for sample seq+1+j */
} ar_actuation_t;

#define AR_ACTUATION_SIZE 4224
#define AR_ACTUATION_ALIGN 8
#define AR_ACTUATION_OFFSET_CONTRACT_VERSION 0
#define AR_ACTUATION_OFFSET_STATUS 4
#define AR_ACTUATION_OFFSET_SEQ 8
#define AR_ACTUATION_OFFSET_REPLY_TO 16
#define AR_ACTUATION_OFFSET_T_SAMPLE_NS 24
#define AR_ACTUATION_OFFSET_T_PUBLISH_NS 32
#define AR_ACTUATION_OFFSET_COMPUTE_NS 40
#define AR_ACTUATION_OFFSET_COUNTS 48
#define AR_ACTUATION_OFFSET_TIMING 56
#define AR_ACTUATION_OFFSET_PLAN_LEN 60
#define AR_ACTUATION_OFFSET_U 64
#define AR_ACTUATION_OFFSET_PLAN 128

#if defined(__STDC_VERSION__) && __STDC_VERSION__ >= 201112L
_Static_assert(sizeof(ar_channel_counts_t) == AR_CHANNEL_COUNTS_SIZE, "ar_channel_counts_t size");
_Static_assert(offsetof(ar_channel_counts_t, n_u) == AR_CHANNEL_COUNTS_OFFSET_N_U, "n_u offset");
_Static_assert(sizeof(ar_measurement_t) == AR_MEASUREMENT_SIZE, "ar_measurement_t size");
_Static_assert(_Alignof(ar_measurement_t) == AR_MEASUREMENT_ALIGN, "ar_measurement_t align");
_Static_assert(offsetof(ar_measurement_t, counts) == AR_MEASUREMENT_OFFSET_COUNTS, "counts offset");
_Static_assert(offsetof(ar_measurement_t, y) == AR_MEASUREMENT_OFFSET_Y, "y offset");
_Static_assert(offsetof(ar_measurement_t, z) == AR_MEASUREMENT_OFFSET_Z, "z offset");
_Static_assert(offsetof(ar_measurement_t, r) == AR_MEASUREMENT_OFFSET_R, "r offset");
_Static_assert(offsetof(ar_measurement_t, u_applied) == AR_MEASUREMENT_OFFSET_U_APPLIED, "u_applied offset");
_Static_assert(sizeof(ar_actuation_t) == AR_ACTUATION_SIZE, "ar_actuation_t size");
_Static_assert(_Alignof(ar_actuation_t) == AR_ACTUATION_ALIGN, "ar_actuation_t align");
_Static_assert(offsetof(ar_actuation_t, compute_ns) == AR_ACTUATION_OFFSET_COMPUTE_NS, "compute_ns offset");
_Static_assert(offsetof(ar_actuation_t, reply_to) == AR_ACTUATION_OFFSET_REPLY_TO, "reply_to offset");
_Static_assert(offsetof(ar_actuation_t, timing) == AR_ACTUATION_OFFSET_TIMING, "timing offset");
_Static_assert(offsetof(ar_actuation_t, u) == AR_ACTUATION_OFFSET_U, "u offset");
_Static_assert(offsetof(ar_actuation_t, plan) == AR_ACTUATION_OFFSET_PLAN, "plan offset");
#endif

#endif /* ADAPTIVE_RIG_CONTRACT_H */
