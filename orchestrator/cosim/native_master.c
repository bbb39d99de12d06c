/*
 * native_master.c: the step loop of auv-cosim's master (orchestrator/cosim/master.py) in C.
 *
 * The Python side resolves a system into raw FMI calls once (plan_steps: function
 * pointers, component pointers, value-reference arrays, counts, trace-buffer addresses in
 * row 0 and row strides in bytes) and hands them here as arrays of Call and Step; this file
 * runs steps k0 <= k < k1 exactly as compile_plan's Python loop does, step k on buffer row
 * k - row0 (row0 = 0: one buffer row per step of the run; row0 = k0: a buffer of one chunk
 * of steps, reused chunk after chunk):
 *
 *   for k: t = k * h (computed, never accumulated)
 *          every exchange call on row k - row0 (Gauss-Seidel: gets and sets in evaluation
 *          order; Jacobi: the sets from that row)
 *          fmi2DoStep(component, t, h, fmi2True) on every FMU in order
 *          if k + 1 < last: every `after` call on row k + 1 - row0 (Jacobi's gets)
 *
 * The FMUs read and write the caller's numpy trace arrays in place, so the traces are the
 * Python master's bit for bit. Before each step the loop reads *stop (set by the Python
 * side when a signal arrived) and returns there; after each step it stores the number of
 * steps done in *reached (the Python side's progress bar reads it). With a Pace of factor
 * > 0 each step waits for its wall-clock deadline (CLOCK_MONOTONIC, absolute sleeps: no
 * drift) and counts the steps that end late. No allocation, no global state: several
 * loops may run at once on different systems.
 *
 * Built by orchestrator/cosim/native_master.py with the system C compiler (libc only).
 */
#define _POSIX_C_SOURCE 200809L
#include <stddef.h>
#include <stdint.h>
#include <time.h>

typedef int (*RealIO)(void *component, const unsigned int *vr, size_t n, double *values);
typedef int (*DoStep)(void *component, double t, double h, int no_prior);

/* one fmi2GetReal / fmi2SetReal: values at base + (k - row0) * stride (bytes) in step k */
typedef struct {
    RealIO fn;
    void *component;
    const unsigned int *vr;
    size_t n;
    char *base;
    int64_t stride;
} Call;

typedef struct {
    DoStep fn;
    void *component;
} Step;

/* real-time pacing (factor > 0): step k may end no earlier than start + (k + 1 - origin) h
 * / factor on CLOCK_MONOTONIC (s); a step that ends later is an overrun */
typedef struct {
    double factor;          /* simulated seconds per wall-clock second; <= 0: no pacing */
    double start;           /* CLOCK_MONOTONIC seconds at which step `origin` began */
    int64_t origin;
    int64_t overruns;       /* steps that ended after their wall-clock deadline */
    double worst;           /* the largest lateness, s */
} Pace;

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* after step k: wait for its deadline, or count the overrun */
static void pace_after(Pace *p, int64_t k, double h)
{
    double deadline = p->start + (double)(k + 1 - p->origin) * h / p->factor;
    double late = now_s() - deadline;
    if (late > 0.0) {
        p->overruns++;
        if (late > p->worst) p->worst = late;
        return;
    }
    struct timespec ts;
    ts.tv_sec = (time_t)deadline;
    ts.tv_nsec = (long)((deadline - (double)ts.tv_sec) * 1e9);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) != 0) {
    }
}

/* where a call failed: phase (0 none, 1 exchange, 2 doStep, 3 after), index, fmi2Status */
typedef struct {
    int32_t phase;
    int32_t index;
    int32_t status;
} Failure;

static int calls(const Call *c, int32_t n, int64_t row, Failure *fail, int32_t phase)
{
    for (int32_t i = 0; i < n; i++) {
        int st = c[i].fn(c[i].component, c[i].vr, c[i].n, (double *)(c[i].base + row * c[i].stride));
        if (st != 0) {
            fail->phase = phase;
            fail->index = i;
            fail->status = st;
            return 1;
        }
    }
    return 0;
}

/*
 * Run steps k0 <= k < k1 of h seconds on buffer rows k - row0; `last` is the number of
 * steps of the whole run (Jacobi reads no outputs after the last one). Returns the number of steps done: k1, or
 * the k at which *stop was found set, or the k of the step whose call failed (then
 * fail->phase != 0).
 */
int64_t auv_master_run(const Call *exchange, int32_t nx, const Step *steps, int32_t ns,
                       const Call *after, int32_t na, int64_t k0, int64_t k1, double h,
                       int64_t last, int64_t row0, const volatile int32_t *stop,
                       volatile int64_t *reached, Failure *fail, Pace *pace)
{
    fail->phase = 0;
    for (int64_t k = k0; k < k1; k++) {
        if (*stop) return k;
        double t = (double)k * h;
        if (calls(exchange, nx, k - row0, fail, 1)) return k;
        for (int32_t i = 0; i < ns; i++) {
            int st = steps[i].fn(steps[i].component, t, h, 1);
            if (st != 0) {
                fail->phase = 2;
                fail->index = i;
                fail->status = st;
                return k;
            }
        }
        if (na && k + 1 < last && calls(after, na, k + 1 - row0, fail, 3)) return k;
        *reached = k + 1;
        if (pace != NULL && pace->factor > 0.0) pace_after(pace, k, h);
    }
    return k1;
}
