/*
 * first_order_plant.c -- a DAQ process in plain C: the first-order plant of
 * scenarios/first-order-lockstep.toml as the plant of the contract, through adaptive_rig.h.
 *
 *   first_order_plant RIG STEPS [lockstep|real-time] [TRACE.csv] [options]
 *     --n-y N        publish N measurement channels (default 1; another count than the
 *                    service's is refused with AR_ERR_MISMATCH, which the tests check)
 *     --latency      record the time from each publish to its input (ar_monotonic_ns) and
 *                    print its p50, p99 and maximum at the end
 *     --json         print the plant's report as JSON at the end
 *
 * The plant G(s) = 1/(s + p), p = 5, sampled every T = 1 ms from x(0) = 1, discretized
 * exactly under a zero-order hold:
 *   x_{k+1} = e^{-pT} x_k + (1 - e^{-pT})/p * u_k,   y_k = z_k = x_k.
 * A real driver reads its ADC where this one reads x, and writes its DAC where this one
 * advances x. The trace has one row per sample: k, y_k, u_k (%.17g, exact round trip).
 *
 * Build (see ipc-types/c/README.md):
 *   cargo build --release -p adaptive-rig-c
 *   cc -std=c11 -O2 -I ipc-types/include ipc-types/c/examples/first_order_plant.c \
 *      target/release/libadaptive_rig.a -lgcc_s -lutil -lrt -lpthread -lm -ldl -lc -o first_order_plant
 */
#include "adaptive_rig.h"

#include <inttypes.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void on_signal(int sig) {
    (void)sig;
    ar_request_stop(); /* async-signal-safe: ends the waits with AR_STOPPED */
}

static int fail(const char* what, ar_status_t rc) {
    fprintf(stderr, "first_order_plant: %s: %s: %s\n", what, ar_status_name(rc), ar_last_error());
    return 1;
}

static int compare_u64(const void* a, const void* b) {
    uint64_t x = *(const uint64_t*)a, y = *(const uint64_t*)b;
    return (x > y) - (x < y);
}

int main(int argc, char** argv) {
    if (argc < 3) {
        fprintf(stderr,
                "usage: first_order_plant RIG STEPS [lockstep|real-time] [TRACE.csv] "
                "[--n-y N] [--latency] [--json]\n");
        return 2;
    }
    const char* rig = argv[1];
    char* end = NULL;
    uint64_t steps = strtoull(argv[2], &end, 10);
    if (*argv[2] == '\0' || *end != '\0') {
        fprintf(stderr, "first_order_plant: STEPS: '%s' is not a whole number\n", argv[2]);
        return 2;
    }
    int lockstep = 1, latency = 0, json = 0;
    unsigned n_y = 1;
    const char* trace_path = NULL;
    int positional = 0;
    for (int i = 3; i < argc; i++) {
        if (strcmp(argv[i], "--n-y") == 0 && i + 1 < argc) {
            n_y = (unsigned)strtoul(argv[++i], NULL, 10);
        } else if (strcmp(argv[i], "--latency") == 0) {
            latency = 1;
        } else if (strcmp(argv[i], "--json") == 0) {
            json = 1;
        } else if (positional == 0) {
            positional++;
            if (strcmp(argv[i], "lockstep") == 0) {
                lockstep = 1;
            } else if (strcmp(argv[i], "real-time") == 0) {
                lockstep = 0;
            } else {
                fprintf(stderr, "first_order_plant: mode '%s' is neither lockstep nor real-time\n",
                        argv[i]);
                return 2;
            }
        } else if (positional == 1) {
            positional++;
            trace_path = argv[i];
        } else {
            fprintf(stderr, "first_order_plant: unexpected argument '%s'\n", argv[i]);
            return 2;
        }
    }
    if (n_y < 1 || n_y > AR_MAX_Y) {
        fprintf(stderr, "first_order_plant: --n-y: 1 to %d\n", AR_MAX_Y);
        return 2;
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);

    /* The plant: G(s) = 1/(s + p), exact ZOH discretization at T. */
    const double p = 5.0;
    const uint64_t period_ns = 1000000;
    const double t_s = (double)period_ns * 1e-9;
    const double a = exp(-p * t_s);
    const double b = (1.0 - a) / p;
    double x = 1.0;

    ar_plant_config_t cfg;
    ar_status_t rc = ar_plant_config_init(&cfg);
    if (rc != AR_OK) return fail("ar_plant_config_init", rc);
    cfg.rig = rig;
    cfg.counts.n_y = (uint16_t)n_y;
    cfg.counts.n_z = 1;
    cfg.counts.n_r = 0;
    cfg.counts.n_u = 1;
    cfg.period_ns = period_ns;
    cfg.mode = lockstep ? AR_MODE_LOCKSTEP : AR_MODE_REAL_TIME;
    cfg.label = "first-order-c";
    cfg.verbose = 1;

    ar_plant_t* plant = NULL;
    rc = ar_plant_open(&cfg, &plant);
    if (rc != AR_OK) return fail("ar_plant_open", rc);
    uint64_t deadline_offset = 0;
    rc = ar_plant_deadline_offset_ns(plant, &deadline_offset);
    if (rc != AR_OK) return fail("ar_plant_deadline_offset_ns", rc);

    FILE* trace = NULL;
    if (trace_path != NULL) {
        trace = fopen(trace_path, "w");
        if (trace == NULL) {
            perror(trace_path);
            ar_plant_close(plant);
            return 1;
        }
        fprintf(trace, "k,y,u\n");
    }
    uint64_t* spans = latency ? calloc(steps > 0 ? steps : 1, sizeof(uint64_t)) : NULL;
    if (latency && spans == NULL) {
        fprintf(stderr, "first_order_plant: out of memory\n");
        return 1;
    }

    double y[AR_MAX_Y];
    const uint64_t t0 = ar_monotonic_ns() + 2 * period_ns;
    uint64_t done = 0;
    int status = 0;
    for (uint64_t k = 0; k < steps; k++) {
        uint64_t t_k;
        if (lockstep) {
            t_k = ar_monotonic_ns();
        } else {
            t_k = t0 + k * period_ns;
            ar_sleep_until_ns(t_k);
        }
        /* The ADC: every measurement channel reads the state. */
        for (unsigned i = 0; i < n_y; i++) y[i] = x;
        const double z = x;
        const uint32_t extra = (k + 1 == steps) ? AR_MEAS_LAST_SAMPLE : 0u;
        const uint64_t t_pub = latency ? ar_monotonic_ns() : 0;
        rc = ar_plant_publish(plant, k, t_k, y, &z, NULL, extra, NULL);
        if (rc != AR_OK) {
            status = fail("ar_plant_publish", rc);
            break;
        }
        double u = 0.0;
        ar_input_kind_t kind = AR_INPUT_ANSWERED;
        if (lockstep) {
            rc = ar_plant_take(plant, k, AR_WAIT_LOCKSTEP, 0, &u, &kind);
        } else {
            rc = ar_plant_take(plant, k, AR_WAIT_AT, t_k + deadline_offset, &u, &kind);
        }
        if (rc == AR_STOPPED) {
            fprintf(stderr, "first_order_plant: stopped at sample %" PRIu64 "\n", k);
            break;
        }
        if (rc != AR_OK) {
            status = fail("ar_plant_take", rc);
            break;
        }
        if (latency) spans[k] = ar_monotonic_ns() - t_pub;
        if (trace != NULL) fprintf(trace, "%" PRIu64 ",%.17g,%.17g\n", k, y[0], u);
        /* The DAC: u holds over the period; the plant advances one period under it. */
        x = a * x + b * u;
        done = k + 1;
    }
    if (trace != NULL) fclose(trace);

    ar_plant_report_t report;
    rc = ar_plant_report(plant, &report);
    if (rc != AR_OK) return fail("ar_plant_report", rc);
    if (json) {
        size_t len = 0;
        ar_plant_report_json(plant, NULL, 0, &len); /* AR_ERR_BUFFER_TOO_SMALL: the length */
        char* buf = malloc(len + 1);
        if (buf != NULL && ar_plant_report_json(plant, buf, len + 1, NULL) == AR_OK) {
            printf("%s\n", buf);
        }
        free(buf);
    }
    ar_plant_close(plant);
    printf("done: %" PRIu64 " samples, %" PRIu64 " actuations applied, %" PRIu64
           " misses, %.6f s, %.3f us per sample\n",
           report.samples, report.actuations_applied, report.misses, report.wall_time_s,
           done > 0 ? report.wall_time_s * 1e6 / (double)done : 0.0);
    if (latency && done > 0) {
        qsort(spans, done, sizeof(uint64_t), compare_u64);
        printf("publish->input: p50 %.3f us, p99 %.3f us, max %.3f us over %" PRIu64 " samples\n",
               spans[done / 2] * 1e-3, spans[(done * 99) / 100] * 1e-3, spans[done - 1] * 1e-3,
               done);
    }
    free(spans);
    return status;
}
