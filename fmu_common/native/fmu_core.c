/*
 * The FMI 2.0 co-simulation plumbing of the project's native FMUs, in plain C99 (libc and
 * libm only): instantiation, the phases, get/set by value reference with checks, the FMU
 * state (get, set, serialize), logging and the error handling. The mathematics is the
 * model's (fmu_core.h: its hooks; linear_fmu.c, guidance_fmu.c, autopilot_fmu.c).
 *
 * Phases (FMI 2.0, 4.2.4): instantiated -> initialization mode -> step mode -> terminated.
 * Outputs are computed from fmi2ExitInitializationMode on (the parameters are final then),
 * lazily, after any input or the state changed; before that they read 0.
 *
 * Errors never crash the host. Each gives a status and a logged message naming the variable
 * (and its value) or the time; a refused call changes nothing, so a host that corrects
 * what it did wrong (sets a finite input, steps from the right point) can go on:
 * - fmi2Instantiate: a NULL or empty instance name, no allocateMemory/freeMemory callback,
 *   a GUID other than this FMU's, the type fmi2ModelExchange (co-simulation only) -> NULL
 *   (logged when a logger was given). The resource location is not used: a missing,
 *   NULL or undecodable one is fine;
 * - fmi2SetupExperiment: after initialization; a start time that is not finite (or not 0
 *   where START_AT_ZERO); a stop time before the start                  -> fmi2Error;
 * - fmi2ExitInitializationMode: a Real parameter that is not finite, or one the model
 *   refuses (model_check: a non-positive mass, a step h <= 0, ...)        -> fmi2Error;
 * - fmi2DoStep: before initialization, in initialization mode or after fmi2Terminate; a
 *   step size that is not a positive finite number, or (STEP_VR >= 0) differs from the
 *   parameter h by more than STEP_SIZE_TOLERANCE h; a communication point that is not the
 *   end of the last step (t0 + the steps taken, within COMM_POINT_TOLERANCE of the step
 *   plus TIME_ROUNDING |t|: fmu_tolerances.h, generated from fmu_common/lifecycle.py);
 *   an input that is not finite (named with its value); a state that would turn
 *   non-finite (the step is not taken)                                  -> fmi2Error;
 * - fmi2GetReal: an output that comes out non-finite (naming it and the first non-finite
 *   input, if one is the cause; the values are written all the same)   -> fmi2Error;
 * - setting a parameter after initialization, setting an output, an unknown value reference,
 *   a state of another FMU, a NULL instance                               -> fmi2Error.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmu_core.h"

#define STATE_MAGIC 0x4155564eu    /* "AUVN" */

/* the number of Integer variables as a variable (NINT may be 0: no "always true" warning) */
static const fmi2ValueReference n_int = NINT;

/* every entry point taking an instance: a NULL one (a host error) is refused, not followed */
#define INSTANCE(c) Instance *in = (Instance *)(c); if (!in) return fmi2Error

/* ------------------------------------------------------------------ messages */
void fmu_log(Instance *in, fmi2Status st, const char *fmt, ...) {
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (in->cb.logger)
        in->cb.logger(in->cb.componentEnvironment, in->name, st,
                      st == fmi2OK ? "logAll" : "logStatusError", "%s", msg);
}

static fmi2Status bad_vr(Instance *in, const char *fn, fmi2ValueReference vr) {
    if (!in) return fmi2Error;
    fmu_log(in, fmi2Error, "%s: no variable has value reference %u", fn, vr);
    return fmi2Error;
}

static void start_values(Data *d) {
    memset(d->r, 0, sizeof d->r);
    memset(d->ints, 0, sizeof d->ints);
    model_start_values(d);
}

static void reset_state(Data *d) {
    d->k = 0;
    d->dirty = 1;
    model_reset(d);
}

/* ------------------------------------------------------------------ FMI: life cycle */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

/* the resource location is not used (everything is compiled in): a NULL, missing or
   undecodable one is accepted */
fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String resources, const fmi2CallbackFunctions *cb,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)resources; (void)visible;
    if (!cb) return NULL;
    Instance tmp;
    memset(&tmp, 0, sizeof tmp);
    tmp.cb = *cb;
    snprintf(tmp.name, sizeof tmp.name, "%s", name ? name : "");
    if (!name || !name[strspn(name, " \t\r\n")]) {
        fmu_log(&tmp, fmi2Error, "fmi2Instantiate refused: the instance name is %s (FMI 2.0 "
                "asks for a non-empty one)", name ? "empty" : "NULL");
        return NULL;
    }
    if (!cb->allocateMemory || !cb->freeMemory) {
        fmu_log(&tmp, fmi2Error, "fmi2Instantiate of instance '%s' refused: the callbacks "
                "have no allocateMemory or freeMemory function", tmp.name);
        return NULL;
    }
    if (type != fmi2CoSimulation) {
        fmu_log(&tmp, fmi2Error, "fmi2Instantiate of instance '%s' refused: the FMU type %d "
                "is not fmi2CoSimulation (%d): this FMU is for co-simulation only", tmp.name,
                (int)type, (int)fmi2CoSimulation);
        return NULL;
    }
    if (!guid || strcmp(guid, NATIVE_GUID) != 0) {
        fmu_log(&tmp, fmi2Error, "fmi2Instantiate of instance '%s' refused: GUID %s does not "
                "match this FMU's %s (a modelDescription.xml of another build?)", tmp.name,
                guid ? guid : "(NULL)", NATIVE_GUID);
        return NULL;
    }
    Instance *in = cb->allocateMemory(1, sizeof(Instance));
    if (!in) return NULL;
    memcpy(in, &tmp, sizeof tmp);
    in->logging = loggingOn;
    Data *d = &in->d;
    d->magic = STATE_MAGIC;
    d->size = (uint32_t)sizeof(Data);
    start_values(d);
    d->t_next = 0.0;
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
    INSTANCE(c);
    in->logging = on;
    return fmi2OK;
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real t0,
                               fmi2Boolean stopDef, fmi2Real t1) {
    (void)tolDef; (void)tol;
    INSTANCE(c);
    if (in->d.phase != INSTANTIATED) {
        fmu_log(in, fmi2Error, "fmi2SetupExperiment is allowed only before "
                "fmi2EnterInitializationMode");
        return fmi2Error;
    }
    if (!isfinite(t0) || (START_AT_ZERO && t0 != 0.0)) {
        fmu_log(in, fmi2Error, "start time %g s: this FMU starts at %s", t0,
                START_AT_ZERO ? "t = 0" : "a finite time");
        return fmi2Error;
    }
    if (stopDef && !(t1 >= t0)) {
        fmu_log(in, fmi2Error, "stop time %g s: it must not be before the start time %g s",
                t1, t0);
        return fmi2Error;
    }
    in->d.t_next = t0;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    INSTANCE(c);
    if (in->d.phase != INSTANTIATED) {
        fmu_log(in, fmi2Error, "fmi2EnterInitializationMode called twice");
        return fmi2Error;
    }
    in->d.phase = INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    INSTANCE(c);
    Data *d = &in->d;
    char nm[96];
    if (d->phase != INIT) {
        fmu_log(in, fmi2Error, "fmi2ExitInitializationMode outside initialization mode");
        return fmi2Error;
    }
    for (int i = 0; i < NPARR; i++) {
        if (!isfinite(d->r[i])) {
            model_real_name((fmi2ValueReference)i, nm, sizeof nm);
            fmu_log(in, fmi2Error, "parameter %s = %g is not finite", nm, d->r[i]);
            return fmi2Error;
        }
    }
    if (model_check(in) != 0) return fmi2Error;
    reset_state(d);
    d->phase = STEPPING;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    INSTANCE(c);
    in->d.phase = TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    INSTANCE(c);
    Data *d = &in->d;
    start_values(d);
    d->t_next = 0.0;
    d->phase = INSTANTIATED;
    reset_state(d);
    return fmi2OK;
}

/* ------------------------------------------------------------------ FMI: values */
/* the first non-finite input's name and value into out ("" if all are finite) */
static void first_bad_input(const Data *d, char *out, size_t n) {
    out[0] = 0;
    for (int i = VR_IN0; i < VR_OUT0; i++) {
        if (!isfinite(d->r[i])) {
            char nm[96];
            model_real_name((fmi2ValueReference)i, nm, sizeof nm);
            snprintf(out, n, "%s = %g", nm, d->r[i]);
            return;
        }
    }
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    INSTANCE(c);
    Data *d = &in->d;
    /* outputs are computed from fmi2ExitInitializationMode on (the parameters are final
       then); in initialization mode they read 0, as the pythonfmu FMUs' do, so a master
       that transfers values during initialization (libcosim) sees the same */
    if ((d->phase == STEPPING || d->phase == TERMINATED) && d->dirty) {
        model_outputs(d);
        d->dirty = 0;
    }
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= NREAL) return bad_vr(in, "fmi2GetReal", vr[i]);
        v[i] = d->r[vr[i]];
    }
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= VR_OUT0 && !isfinite(v[i])) {
            char nm[96], cause[160];
            model_real_name(vr[i], nm, sizeof nm);
            first_bad_input(d, cause, sizeof cause);
            fmu_log(in, fmi2Error, "output %s = %g at t = %g s is not finite%s%s", nm, v[i],
                    d->t_next, cause[0] ? ": input " : "", cause);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real v[]) {
    INSTANCE(c);
    Data *d = &in->d;
    char nm[96];
    for (size_t i = 0; i < n; i++) {
        fmi2ValueReference r = vr[i];
        if (r >= VR_IN0 && r < VR_OUT0) { d->r[r] = v[i]; d->dirty = 1; continue; }
        if (r < NPARR) {
            if (d->phase != INSTANTIATED && d->phase != INIT) {
                model_real_name(r, nm, sizeof nm);
                fmu_log(in, fmi2Error, "parameter %s is fixed after initialization", nm);
                return fmi2Error;
            }
            d->r[r] = v[i];
            continue;
        }
        if (r < NREAL) {
            model_real_name(r, nm, sizeof nm);
            fmu_log(in, fmi2Error, "%s is an output: it cannot be set", nm);
            return fmi2Error;
        }
        return bad_vr(in, "fmi2SetReal", r);
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          fmi2Integer v[]) {
    INSTANCE(c);
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= n_int) return bad_vr(in, "fmi2GetInteger", vr[i]);
        v[i] = in->d.ints[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                          const fmi2Integer v[]) {
    INSTANCE(c);
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= n_int) return bad_vr(in, "fmi2SetInteger", vr[i]);
        if (in->d.phase != INSTANTIATED && in->d.phase != INIT) {
            fmu_log(in, fmi2Error, "parameter %s is fixed after initialization",
                    model_int_name(vr[i]));
            return fmi2Error;
        }
        in->d.ints[vr[i]] = v[i];
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
#if NSTRING > 0
/* String parameters are fixed at export: readable, and settable to that value only */
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    INSTANCE(c);
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= NSTRING) return bad_vr(in, "fmi2GetString", vr[i]);
        v[i] = model_string_value(vr[i]);
    }
    return fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String v[]) {
    INSTANCE(c);
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= NSTRING) return bad_vr(in, "fmi2SetString", vr[i]);
        const char *fixed = model_string_value(vr[i]);
        if (!v[i] || strcmp(v[i], fixed) != 0) {
            fmu_log(in, fmi2Error, "parameter %s = '%s' differs from '%s', the value this "
                    "native FMU was exported with (export it again with this value)",
                    model_string_name(vr[i]), v[i] ? v[i] : "(NULL)", fixed);
            return fmi2Error;
        }
    }
    return fmi2OK;
}
#else
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    (void)v; return n ? bad_vr(c, "fmi2GetString", vr[0]) : fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                         const fmi2String v[]) {
    (void)v; return n ? bad_vr(c, "fmi2SetString", vr[0]) : fmi2OK;
}
#endif

/* ------------------------------------------------------------------ FMI: stepping */
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real step, fmi2Boolean noPrior) {
    (void)noPrior;
    INSTANCE(c);
    Data *d = &in->d;
    char nm[96];
    if (d->phase != STEPPING) {
        fmu_log(in, fmi2Error, "fmi2DoStep at t = %g s refused: called %s", t,
                d->phase == INSTANTIATED ? "before initialization (fmi2EnterInitializationMode "
                "and fmi2ExitInitializationMode come first)" :
                d->phase == INIT ? "in initialization mode (call fmi2ExitInitializationMode "
                "first)" : "after fmi2Terminate (fmi2Reset or instantiate again)");
        return fmi2Error;
    }
    if (!(step > 0.0) || !isfinite(step)) {
        fmu_log(in, fmi2Error, "communication step %g s at t = %g s: the step size must be a "
                "positive number", step, t);
        return fmi2Error;
    }
    if (STEP_VR >= 0) {
        double h = d->r[STEP_VR];
        if (fabs(step - h) > STEP_SIZE_TOLERANCE * h) {
            fmu_log(in, fmi2Error, "communication step %g s at t = %g s: this FMU is designed "
                    "for h = %g s (a step within %g h of it)", step, t, h,
                    STEP_SIZE_TOLERANCE);
            return fmi2Error;
        }
    }
    double tol = COMM_POINT_TOLERANCE * step + TIME_ROUNDING * fabs(d->t_next);
    if (!isfinite(t) || fabs(t - d->t_next) > tol) {
        fmu_log(in, fmi2Error, "communication point t = %.17g s: this FMU expects t = %.17g s "
                "(the end of its last step, within %g s); to repeat a step, restore a state "
                "with fmi2SetFMUstate first", t, d->t_next, tol);
        return fmi2Error;
    }
    for (int i = VR_IN0; i < VR_OUT0; i++) {
        if (!isfinite(d->r[i])) {
            model_real_name((fmi2ValueReference)i, nm, sizeof nm);
            fmu_log(in, fmi2Error, "step at t = %g s refused: input %s = %g is not finite "
                    "(set it to a finite value and step again)", t, nm, d->r[i]);
            return fmi2Error;
        }
    }
    if (d->dirty) {
        model_outputs(d);
        d->dirty = 0;
    }
    if (model_step(in, t, step) != 0) return fmi2Error;
    d->k += 1;
    d->t_next = t + step;
    d->dirty = 1;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    INSTANCE(c);
    fmu_log(in, fmi2Error, "fmi2CancelStep: no asynchronous steps here");
    return fmi2Error;
}

static fmi2Status no_status(Instance *in, const char *what) {
    if (!in) return fmi2Error;
    fmu_log(in, fmi2Error, "%s: no asynchronous steps here", what);
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
    INSTANCE(c);
    fmu_log(in, fmi2Error, "input derivatives are not supported");
    return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[]) {
    (void)vr; (void)n; (void)o; (void)v;
    INSTANCE(c);
    fmu_log(in, fmi2Error, "output derivatives are not supported");
    return fmi2Error;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz,
                                        const fmi2Real du[], fmi2Real dz[]) {
    (void)u; (void)nu; (void)z; (void)nz; (void)du; (void)dz;
    INSTANCE(c);
    fmu_log(in, fmi2Error, "directional derivatives are not supported");
    return fmi2Error;
}

/* ------------------------------------------------------------------ FMI: state */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) {
    INSTANCE(c);
    if (!s) { fmu_log(in, fmi2Error, "fmi2GetFMUstate: no place for the state (NULL)"); return fmi2Error; }
    Data *copy = *s ? (Data *)*s : in->cb.allocateMemory(1, sizeof(Data));
    if (!copy) return fmi2Error;
    memcpy(copy, &in->d, sizeof(Data));
    *s = copy;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) {
    INSTANCE(c);
    const Data *src = s;
    if (!src) { fmu_log(in, fmi2Error, "fmi2SetFMUstate: no state"); return fmi2Error; }
    if (src->magic != STATE_MAGIC || src->size != sizeof(Data)) {
        fmu_log(in, fmi2Error, "not a state of this FMU");
        return fmi2Error;
    }
    memcpy(&in->d, src, sizeof(Data));
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) {
    INSTANCE(c);
    if (s && *s) { in->cb.freeMemory(*s); *s = NULL; }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    (void)s;
    INSTANCE(c);
    if (!size) return fmi2Error;
    *size = sizeof(Data);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte out[], size_t size) {
    INSTANCE(c);
    if (!s || !out) { fmu_log(in, fmi2Error, "fmi2SerializeFMUstate: no state or no buffer"); return fmi2Error; }
    if (size < sizeof(Data)) { fmu_log(in, fmi2Error, "serialized state buffer too small"); return fmi2Error; }
    memcpy(out, s, sizeof(Data));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte in_[], size_t size,
                                   fmi2FMUstate *s) {
    INSTANCE(c);
    Data tmp;
    if (!in_ || !s) { fmu_log(in, fmi2Error, "fmi2DeSerializeFMUstate: no bytes or no place for the state"); return fmi2Error; }
    if (size != sizeof(Data)) {
        fmu_log(in, fmi2Error, "a serialized state of %zu bytes; this FMU's has %zu", size, sizeof(Data));
        return fmi2Error;
    }
    memcpy(&tmp, in_, sizeof(Data));
    if (tmp.magic != STATE_MAGIC) { fmu_log(in, fmi2Error, "not a state of this FMU"); return fmi2Error; }
    Data *copy = in->cb.allocateMemory(1, sizeof(Data));
    if (!copy) return fmi2Error;
    memcpy(copy, &tmp, sizeof(Data));
    *s = copy;
    return fmi2OK;
}
