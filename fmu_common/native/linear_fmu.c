/*
 * A discrete-time linear system as an FMI 2.0 co-simulation FMU, in plain C99 (libc and
 * libm only). Every designed FMU of auv-cosim (controller, estimator, linear plant) is such a
 * system once its Riccati and Sylvester equations are solved; the numbers come from the
 * generated header "native_model.h" (sizes, value references, start values, names).
 *
 * At communication point t_k, with the inputs u (NU Reals, as set by the host), the state
 * q (NQ) and the noise draw xi (NXI standard normals of step k):
 *
 *     y      = C q + D u + c + G xi                     (outputs, NY; D: direct feedthrough)
 *     y_j    = min(max(y_j, -s_j), s_j)                 (rows row0.. of the role sat, if any:
 *                                                        a controller's force limit u_max)
 *     q(k+1) = A q + B u + Bo y + b + F xi              (fmi2DoStep, step = h)
 *
 * A matrix that the header leaves out is zero; B and D act on a contiguous range of the
 * inputs (their col0 in the ROLE table). The noise is numpy's (numpy_random.c): xi is
 * filled stream by stream (the header's STREAMS table), each stream a PCG64 generator seeded
 * as numpy.random.default_rng(seed) or default_rng([seed, key]) seeds it and drawing its
 * count of ziggurat normals per step in order, so xi is bit for bit the standard normal
 * row a pythonfmu plant of the same seed draws (plant_model.plant.NoiseStream).
 *
 * Value references (Real): 0 .. NPAR-1 the parameter entries, row major, in the order of
 * the header's ROLE table; NPAR: h; then the NU inputs, then the NY outputs. Integer: 0 seed
 * (only with noise), 1 stream (the key of the one keyed stream, if HAS_STREAM_PARAM).
 *
 * Errors never crash the host: a bad parameter (not finite), a step other than h, a state
 * that turns non-finite or a call in the wrong state gives fmi2Error and a logged message
 * naming the variable or the time.
 */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "numpy_random.h"

#define ALLOC(n) ((n) > 0 ? (n) : 1)
typedef struct {
    const char *name;
    unsigned offset, rows, cols, row0, col0;
    double sign;
    int vector;
} RoleInfo;
typedef struct {
    int keyed;              /* default_rng([seed, key]) if 1, default_rng(seed) if 0 */
    uint32_t key;
    unsigned count;         /* normals per step, xi[offset .. offset + count) */
} StreamInfo;

#include "native_model.h"

#define NREAL (NPAR + 1 + NU + NY)
#define VR_H NPAR
#define VR_U (NPAR + 1)
#define VR_Y (NPAR + 1 + NU)

typedef enum { INSTANTIATED, INIT, STEPPING, TERMINATED } Phase;

/* everything that evolves or is set: one block, copied whole as the FMU state */
typedef struct {
    uint32_t magic, size;
    double par[ALLOC(NPAR)];
    double h;
    double u[ALLOC(NU)];
    double y[ALLOC(NY)];
    double q[ALLOC(NQ)];
    double xi[ALLOC(NXI)];
    NprPcg64 rng[ALLOC(NSTREAMS)];   /* one numpy PCG64 per noise stream */
    int seed, stream;
    int64_t k;
    int dirty;              /* y must be recomputed (an input or the state changed) */
    Phase phase;
} Data;

typedef struct {
    Data d;
    fmi2CallbackFunctions cb;
    char name[128];
    int logging;
} Instance;

#define STATE_MAGIC 0x4155564eu    /* "AUVN" */

/* ------------------------------------------------------------------ messages */
static void logf_(Instance *in, fmi2Status st, const char *fmt, ...) {
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (in->cb.logger)
        in->cb.logger(in->cb.componentEnvironment, in->name, st,
                      st == fmi2OK ? "logAll" : "logStatusError", "%s", msg);
}

/* "K[2,3]" for a parameter entry, "h", "u[2]"-style names for the rest */
static void var_name(fmi2ValueReference vr, char *out, size_t n) {
    if (vr < NPAR) {
        for (int r = 0; r < NROLES; r++) {
            const RoleInfo *ri = &ROLES[r];
            if (vr >= ri->offset && vr < ri->offset + ri->rows * ri->cols) {
                unsigned i = vr - ri->offset;
                if (ri->cols == 1 && ri->vector)
                    snprintf(out, n, "%s[%u]", ri->name, i + 1);
                else
                    snprintf(out, n, "%s[%u,%u]", ri->name, i / ri->cols + 1, i % ri->cols + 1);
                return;
            }
        }
    }
    if (vr >= VR_U && vr < VR_Y) snprintf(out, n, "%s", INPUT_NAMES[vr - VR_U]);
    else if (vr >= VR_Y && vr < NREAL) snprintf(out, n, "%s", OUTPUT_NAMES[vr - VR_Y]);
    else if (vr == VR_H) snprintf(out, n, "h");
    else snprintf(out, n, "value reference %u", vr);
}

/* ------------------------------------------------------------------ noise */
static void seed_rng(Data *d) {
    for (int i = 0; i < NSTREAMS; i++) {
        uint64_t entropy[2] = {(uint64_t)(uint32_t)d->seed,
                               HAS_STREAM_PARAM && i == 0 ? (uint64_t)(uint32_t)d->stream
                                                          : (uint64_t)STREAMS[i].key};
        npr_seed(&d->rng[i], entropy, STREAMS[i].keyed ? 2 : 1);
    }
}

/* xi of the step: stream by stream, as many normals as numpy's standard_normal((n, count))
   takes per row */
static void draw(Data *d) {
    int j = 0;
    for (int i = 0; i < NSTREAMS; i++)
        for (unsigned c = 0; c < STREAMS[i].count; c++)
            d->xi[j++] = npr_standard_normal(&d->rng[i]);
}

/* ------------------------------------------------------------------ the equations */
/* out += M v[col0 ...] for the role r (rows x cols, row major in par) */
static void gemv_add(const Data *d, int r, const double *v, double *out) {
    if (r < 0) return;
    const RoleInfo *ri = &ROLES[r];
    const double *M = d->par + ri->offset;
    v += ri->col0;
    out += ri->row0;
    for (unsigned i = 0; i < ri->rows; i++) {
        double acc = 0.0;
        const double *row = M + (size_t)i * ri->cols;
        for (unsigned j = 0; j < ri->cols; j++) acc += row[j] * v[j];
        out[i] += ri->sign * acc;
    }
}

static void add_vector(const Data *d, int r, double *out) {
    if (r < 0) return;
    const RoleInfo *ri = &ROLES[r];
    for (unsigned i = 0; i < ri->rows; i++) out[i] += ri->sign * d->par[ri->offset + i];
}

/* y[row0 + i] clipped to [-s_i, s_i] for the role r (a vector of limits) */
static void clip(const Data *d, int r, double *y) {
    if (r < 0) return;
    const RoleInfo *ri = &ROLES[r];
    y += ri->row0;
    for (unsigned i = 0; i < ri->rows; i++) {
        double lim = d->par[ri->offset + i];
        y[i] = y[i] < -lim ? -lim : y[i];                /* numpy.maximum(y, -lim) */
        y[i] = y[i] > lim ? lim : y[i];                  /* numpy.minimum(., lim) */
    }
}

static void outputs(Data *d) {
    if (!d->dirty) return;
    for (int i = 0; i < NY; i++) d->y[i] = 0.0;
    gemv_add(d, ROLE_C, d->q, d->y);
    gemv_add(d, ROLE_D, d->u, d->y);
    add_vector(d, ROLE_c, d->y);
    gemv_add(d, ROLE_G, d->xi, d->y);
    clip(d, ROLE_sat, d->y);
    d->dirty = 0;
}

static void reset_state(Data *d) {
    for (int i = 0; i < NQ; i++) d->q[i] = ROLE_q0 >= 0 ? d->par[ROLES[ROLE_q0].offset + i] : 0.0;
    d->k = 0;
    seed_rng(d);
    draw(d);
    d->dirty = 1;
}

/* ------------------------------------------------------------------ FMI: life cycle */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String resources, const fmi2CallbackFunctions *cb,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)resources; (void)visible;
    if (!cb || !cb->allocateMemory || !cb->freeMemory) return NULL;
    Instance tmp = {0};
    tmp.cb = *cb;
    snprintf(tmp.name, sizeof tmp.name, "%s", name ? name : "");
    if (type != fmi2CoSimulation || !guid || strcmp(guid, NATIVE_GUID) != 0) {
        logf_(&tmp, fmi2Error, type != fmi2CoSimulation ? "co-simulation only" :
              "GUID %s does not match this FMU's %s", guid ? guid : "(null)", NATIVE_GUID);
        return NULL;
    }
    Instance *in = cb->allocateMemory(1, sizeof(Instance));
    if (!in) return NULL;
    memcpy(in, &tmp, sizeof tmp);
    in->logging = loggingOn;
    Data *d = &in->d;
    d->magic = STATE_MAGIC;
    d->size = (uint32_t)sizeof(Data);
    for (int i = 0; i < NPAR; i++) d->par[i] = PAR_START[i];
    d->h = H_START;
    d->seed = SEED_START;
    d->stream = STREAM_START;
    d->phase = INSTANTIATED;
    reset_state(d);
    return in;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *in = c;
    if (in) in->cb.freeMemory(in);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) {
    (void)n; (void)cat;
    ((Instance *)c)->logging = on;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real t0,
                               fmi2Boolean stopDef, fmi2Real t1) {
    (void)tolDef; (void)tol; (void)stopDef; (void)t1;
    Instance *in = c;
    if (t0 != 0.0 && NQ > 0) {
        logf_(in, fmi2Error, "start time %g s: this FMU starts at t = 0", t0);
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *in = c;
    if (in->d.phase != INSTANTIATED) {
        logf_(in, fmi2Error, "fmi2EnterInitializationMode called twice");
        return fmi2Error;
    }
    in->d.phase = INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *in = c;
    Data *d = &in->d;
    char nm[96];
    if (d->phase != INIT) {
        logf_(in, fmi2Error, "fmi2ExitInitializationMode outside initialization mode");
        return fmi2Error;
    }
    for (int i = 0; i < NPAR; i++) {
        if (!isfinite(d->par[i])) {
            var_name((fmi2ValueReference)i, nm, sizeof nm);
            logf_(in, fmi2Error, "parameter %s = %g is not finite", nm, d->par[i]);
            return fmi2Error;
        }
    }
    if (ROLE_sat >= 0) {
        for (unsigned i = 0; i < ROLES[ROLE_sat].rows; i++) {
            unsigned vr = ROLES[ROLE_sat].offset + i;
            if (!(d->par[vr] > 0.0)) {
                var_name((fmi2ValueReference)vr, nm, sizeof nm);
                logf_(in, fmi2Error, "parameter %s = %g must be a positive force in N (the "
                      "actuator limit)", nm, d->par[vr]);
                return fmi2Error;
            }
        }
    }
    if (!(d->h > 0.0) || !isfinite(d->h)) {
        logf_(in, fmi2Error, "parameter h = %g s must be a positive number", d->h);
        return fmi2Error;
    }
    if (NXI > 0 && (d->seed < 0 || (HAS_STREAM_PARAM && d->stream < 0))) {
        logf_(in, fmi2Error, "parameter %s = %d must not be negative",
              d->seed < 0 ? "seed" : "stream", d->seed < 0 ? d->seed : d->stream);
        return fmi2Error;
    }
    reset_state(d);
    d->phase = STEPPING;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) { ((Instance *)c)->d.phase = TERMINATED; return fmi2OK; }

fmi2Status fmi2Reset(fmi2Component c) {
    Data *d = &((Instance *)c)->d;
    for (int i = 0; i < NPAR; i++) d->par[i] = PAR_START[i];
    d->h = H_START; d->seed = SEED_START; d->stream = STREAM_START;
    for (int i = 0; i < NU; i++) d->u[i] = 0.0;
    d->phase = INSTANTIATED;
    reset_state(d);
    return fmi2OK;
}

/* ------------------------------------------------------------------ FMI: values */
static fmi2Status bad_vr(Instance *in, const char *fn, fmi2ValueReference vr) {
    logf_(in, fmi2Error, "%s: no variable has value reference %u", fn, vr);
    return fmi2Error;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Instance *in = c;
    Data *d = &in->d;
    /* outputs are computed from fmi2ExitInitializationMode on (the parameters are final
       then); in initialization mode they read 0, as the pythonfmu FMUs' do, so a master
       that transfers values during initialization (libcosim) sees the same */
    if (d->phase == STEPPING || d->phase == TERMINATED) outputs(d);
    for (size_t i = 0; i < n; i++) {
        fmi2ValueReference r = vr[i];
        if (r < NPAR) v[i] = d->par[r];
        else if (r == VR_H) v[i] = d->h;
        else if (r < VR_Y) v[i] = d->u[r - VR_U];
        else if (r < NREAL) v[i] = d->y[r - VR_Y];
        else return bad_vr(in, "fmi2GetReal", r);
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real v[]) {
    Instance *in = c;
    Data *d = &in->d;
    char nm[96];
    for (size_t i = 0; i < n; i++) {
        fmi2ValueReference r = vr[i];
        if (r >= VR_U && r < VR_Y) { d->u[r - VR_U] = v[i]; d->dirty = 1; continue; }
        if (r <= VR_H) {
            if (d->phase != INSTANTIATED && d->phase != INIT) {
                var_name(r, nm, sizeof nm);
                logf_(in, fmi2Error, "parameter %s is fixed after initialization", nm);
                return fmi2Error;
            }
            if (r == VR_H) d->h = v[i]; else d->par[r] = v[i];
            continue;
        }
        if (r < NREAL) {
            var_name(r, nm, sizeof nm);
            logf_(in, fmi2Error, "%s is an output: it cannot be set", nm);
            return fmi2Error;
        }
        return bad_vr(in, "fmi2SetReal", r);
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Integer v[]) {
    Instance *in = c;
    for (size_t i = 0; i < n; i++) {
        if (NXI > 0 && vr[i] == 0) v[i] = in->d.seed;
        else if (HAS_STREAM_PARAM && vr[i] == 1) v[i] = in->d.stream;
        else return bad_vr(in, "fmi2GetInteger", vr[i]);
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer v[]) {
    Instance *in = c;
    for (size_t i = 0; i < n; i++) {
        if (!((NXI > 0 && vr[i] == 0) || (HAS_STREAM_PARAM && vr[i] == 1)))
            return bad_vr(in, "fmi2SetInteger", vr[i]);
        if (in->d.phase != INSTANTIATED && in->d.phase != INIT) {
            logf_(in, fmi2Error, "parameter %s is fixed after initialization",
                  vr[i] == 0 ? "seed" : "stream");
            return fmi2Error;
        }
        if (vr[i] == 0) in->d.seed = v[i]; else in->d.stream = v[i];
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    (void)v; return n ? bad_vr(c, "fmi2GetBoolean", vr[0]) : fmi2OK;
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Boolean v[]) {
    (void)v; return n ? bad_vr(c, "fmi2SetBoolean", vr[0]) : fmi2OK;
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)v; return n ? bad_vr(c, "fmi2GetString", vr[0]) : fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String v[]) {
    (void)v; return n ? bad_vr(c, "fmi2SetString", vr[0]) : fmi2OK;
}

/* ------------------------------------------------------------------ FMI: stepping */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real step, fmi2Boolean noPrior) {
    (void)noPrior;
    Instance *in = c;
    Data *d = &in->d;
    if (d->phase != STEPPING) {
        logf_(in, fmi2Error, "fmi2DoStep at t = %g s outside the stepping phase", t);
        return fmi2Error;
    }
    if (NQ > 0 && fabs(step - d->h) > 1e-9 * d->h) {
        logf_(in, fmi2Error, "communication step %g s at t = %g s: this FMU is designed for "
              "h = %g s", step, t, d->h);
        return fmi2Error;
    }
    outputs(d);
    double next[ALLOC(NQ)];
    for (int i = 0; i < NQ; i++) next[i] = 0.0;
    gemv_add(d, ROLE_A, d->q, next);
    gemv_add(d, ROLE_B, d->u, next);
    gemv_add(d, ROLE_Bo, d->y, next);
    add_vector(d, ROLE_b, next);
    gemv_add(d, ROLE_F, d->xi, next);
    for (int i = 0; i < NQ; i++) {
        if (!isfinite(next[i])) {
            logf_(in, fmi2Error, "%s: state %d is not finite after the step at t = %g s",
                  in->name, i + 1, t);
            return fmi2Error;
        }
    }
    memcpy(d->q, next, sizeof(double) * NQ);
    d->k += 1;
    draw(d);
    d->dirty = 1;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

static fmi2Status no_status(Instance *in, const char *what) {
    logf_(in, fmi2Error, "%s: no asynchronous steps here", what);
    return fmi2Error;
}
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) {
    (void)s; (void)v; return no_status(c, "fmi2GetStatus");
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) {
    (void)s; (void)v; return no_status(c, "fmi2GetRealStatus");
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) {
    (void)s; (void)v; return no_status(c, "fmi2GetIntegerStatus");
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) {
    (void)s; (void)v; return no_status(c, "fmi2GetBooleanStatus");
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) {
    (void)s; (void)v; return no_status(c, "fmi2GetStringStatus");
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[]) {
    (void)vr; (void)n; (void)o; (void)v;
    logf_(c, fmi2Error, "input derivatives are not supported");
    return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[]) {
    (void)vr; (void)n; (void)o; (void)v;
    logf_(c, fmi2Error, "output derivatives are not supported");
    return fmi2Error;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz,
                                        const fmi2Real du[], fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)du; (void)dz;
    logf_(c, fmi2Error, "directional derivatives are not supported");
    return fmi2Error;
}

/* ------------------------------------------------------------------ FMI: state */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) {
    Instance *in = c;
    Data *copy = *s ? (Data *)*s : in->cb.allocateMemory(1, sizeof(Data));
    if (!copy) return fmi2Error;
    memcpy(copy, &in->d, sizeof(Data));
    *s = copy;
    return fmi2OK;
}

static fmi2Status restore(Instance *in, const Data *src) {
    if (src->magic != STATE_MAGIC || src->size != sizeof(Data)) {
        logf_(in, fmi2Error, "not a state of this FMU");
        return fmi2Error;
    }
    memcpy(&in->d, src, sizeof(Data));
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
    if (!s) { logf_(c, fmi2Error, "fmi2SetFMUstate: no state"); return fmi2Error; }
    return restore(c, (const Data *)s);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) {
    Instance *in = c;
    if (s && *s) { in->cb.freeMemory(*s); *s = NULL; }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    (void)c; (void)s; *size = sizeof(Data); return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte out[], size_t size) {
    if (size < sizeof(Data)) { logf_(c, fmi2Error, "serialized state buffer too small"); return fmi2Error; }
    memcpy(out, s, sizeof(Data));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte in_[], size_t size,
                                   fmi2FMUstate *s) {
    Instance *in = c;
    Data tmp;
    if (size != sizeof(Data)) {
        logf_(in, fmi2Error, "a serialized state of %zu bytes; this FMU's has %zu", size, sizeof(Data));
        return fmi2Error;
    }
    memcpy(&tmp, in_, sizeof(Data));
    if (tmp.magic != STATE_MAGIC) { logf_(in, fmi2Error, "not a state of this FMU"); return fmi2Error; }
    Data *copy = in->cb.allocateMemory(1, sizeof(Data));
    if (!copy) return fmi2Error;
    memcpy(copy, &tmp, sizeof(Data));
    *s = copy;
    return fmi2OK;
}
