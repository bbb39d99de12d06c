/*
 * AuvRemus6dof and AuvRemus6dofActuated as native FMUs on the shared FMI plumbing
 * (fmu_core.c), in plain C99: the nonlinear 6-DOF REMUS 100 of remus6dof_model.c (the
 * equations, RK4 sub-steps, autopilot, noise and navigation sensors of
 * plant_model/remus100/kernel.py, plant.py and plant_model/navigation.py) behind the
 * variables of the pythonfmu FMU (plant_model/remus100/remus6dof_slave_base.py; the
 * generated native_model.h is made from its modelDescription by
 * orchestrator/cosim/native_remus.py), so a host swaps one for the other by file name.
 *
 * What is computed here from the parameters at fmi2ExitInitializationMode: the start
 * state from x0 = [p (m); v_g (m/s)] and w0 (m/s) (the nose along v_g - w0, the propeller
 * at n_max |v_g - w0| / U_max), the autopilot gains (autopilot.*), the sub-steps
 * round(h / substep), the generators default_rng([seed, vehicle]) and default_rng([seed,
 * 3000000 + vehicle]). What was computed at export (RemusConst BUILD_CONST: the mass
 * matrix and its inverse, the damping, the strips, the current's transition exp(K h) and
 * the noise factor, which need a matrix exponential and eigen-decompositions): the
 * parameters it came from (FIXED_VRS: the design model's matrices, h, remus.*, sensors.*;
 * and the String noise_convention, refused by fmu_core.c's fmi2SetString) are refused at
 * initialization with another value, naming the parameter (export again).
 * Also refused, by name: autopilot.U_max, n_max, delta_max not positive, U_min negative,
 * a substep that does not divide h, vehicle < 1, seed < 0. A non-finite input is refused by
 * fmu_core.c; a state that would become non-finite ends the step with fmi2Error naming the
 * vehicle and the time, the state left as it was.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#define NATIVE_MODEL_TABLES
#include "fmu_core.h"

#if !defined(VR_x0) || !defined(VR_w0) || !defined(VR_substep) || !defined(VR_autopilot_U_max) \
    || !defined(VR_y) || !defined(VR_saturated)
#error "native_model.h is not AuvRemus6dof's or AuvRemus6dofActuated's"
#endif

void model_start_values(Data *d) {
    for (int i = 0; i < VR_OUT0; i++) d->r[i] = REAL_START[i];
    d->ints[0] = SEED_START;
    d->ints[1] = VEHICLE_START;
}

void model_real_name(fmi2ValueReference vr, char *out, size_t n) {
    if (vr < NREAL) snprintf(out, n, "%s", REAL_NAMES[vr]);
    else snprintf(out, n, "value reference %u", vr);
}

const char *model_int_name(fmi2ValueReference vr) { return vr == 0 ? "seed" : "vehicle"; }

/* noise_convention: the noise factor it selects is in BUILD_CONST */
const char *model_string_name(fmi2ValueReference vr) { (void)vr; return "noise_convention"; }
const char *model_string_value(fmi2ValueReference vr) { (void)vr; return NOISE_CONVENTION; }

/* round(h / substep) if substep divides h (plant.substep_count), else 0 */
static int substep_count(double h, double substep) {
    if (!(substep > 0.0) || !isfinite(substep)) return 0;
    double k = nearbyint(h / substep);
    if (k < 1.0 || k > 1e7 || fabs(k * substep - h) > 1e-9 * h) return 0;
    return (int)k;
}

int model_check(Instance *in) {
    const double *r = in->d.r;
    for (size_t i = 0; i < sizeof FIXED_VRS / sizeof FIXED_VRS[0]; i++) {
        int vr = FIXED_VRS[i];
        if (r[vr] != REAL_START[vr]) {
            fmu_log(in, fmi2Error, "parameter %s = %.17g differs from %.17g, the value this "
                    "native FMU was exported with: the vehicle's mass, damping, current and "
                    "noise numbers are computed at export (export it again with this value)",
                    REAL_NAMES[vr], r[vr], REAL_START[vr]);
            return -1;
        }
    }
    static const int positive[] = {VR_autopilot_U_max, VR_autopilot_n_max
#ifdef VR_autopilot_delta_max
                                   , VR_autopilot_delta_max
#endif
    };
    for (size_t i = 0; i < sizeof positive / sizeof positive[0]; i++) {
        if (!(r[positive[i]] > 0.0)) {
            fmu_log(in, fmi2Error, "parameter %s = %g must be positive", REAL_NAMES[positive[i]],
                    r[positive[i]]);
            return -1;
        }
    }
    if (!(r[VR_autopilot_U_min] >= 0.0)) {
        fmu_log(in, fmi2Error, "parameter autopilot.U_min = %g m/s must not be negative",
                r[VR_autopilot_U_min]);
        return -1;
    }
    if (substep_count(r[VR_h], r[VR_substep]) == 0) {
        fmu_log(in, fmi2Error, "parameter substep = %g s must be positive and divide the step "
                "h = %g s", r[VR_substep], r[VR_h]);
        return -1;
    }
    if (in->d.ints[0] < 0) {
        fmu_log(in, fmi2Error, "parameter seed = %d must not be negative", in->d.ints[0]);
        return -1;
    }
    if (in->d.ints[1] < 1) {
        fmu_log(in, fmi2Error, "parameter vehicle = %d must be 1 or more", in->d.ints[1]);
        return -1;
    }
    return 0;
}

void model_reset(Data *d) {
    const double *r = d->r;
    RemusConst *c = &d->m.c;
    *c = BUILD_CONST;
    /* kernel.pack_gains of the parameters (the actuated FMU has only U_max, n_max, U_min) */
    c->g[0] = r[VR_autopilot_U_max];
    c->g[1] = r[VR_autopilot_n_max];
    c->g[10] = r[VR_autopilot_U_min];
#ifdef VR_autopilot_K_u
    static const int more[] = {VR_autopilot_K_u, VR_autopilot_K_ui, VR_autopilot_K_chi,
                               VR_autopilot_K_r, VR_autopilot_K_gamma, VR_autopilot_K_gi,
                               VR_autopilot_K_theta, VR_autopilot_K_q};
    for (int i = 0; i < 8; i++) c->g[2 + i] = r[more[i]];
    c->g[11] = r[VR_autopilot_delta_max];
#endif
    int k = substep_count(r[VR_h], r[VR_substep]);
    c->substeps = k > 0 ? k : 1;       /* refused by model_check before a step is taken */
    remus_reset(c, &d->m.st, r + VR_x0, r + VR_w0, (uint32_t)d->ints[0], (uint32_t)d->ints[1]);
}

void model_outputs(Data *d) { remus_outputs(&d->m.c, &d->m.st, d->r + VR_OUT0); }

int model_step(Instance *in, double t, double step) {
    (void)step;
    if (remus_step(&in->d.m.c, &in->d.m.st, in->d.r + VR_IN0) != 0) {
        fmu_log(in, fmi2Error, "%s (vehicle %d): the state would become non-finite in the "
                "step from t = %g s to %g s (the step is not taken)", in->name, in->d.ints[1],
                t, t + in->d.r[VR_h]);
        return -1;
    }
    return 0;
}
