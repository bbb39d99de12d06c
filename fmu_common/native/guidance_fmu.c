/*
 * AuvGuidance as a native FMU on the shared FMI plumbing (fmu_core.c), in plain C99: the
 * formation controller's NED force u (N) in; the speed, course and depth set-points and
 * their rates out, through the design model's reference velocity. The same mathematics as
 * controller_fmu/guidance.py and the same interface as the pythonfmu AuvGuidance
 * (controller_fmu/auv_guidance_slave.py: the generated native_model.h is made from its
 * modelDescription), so a host can swap one for the other.
 *
 * Per NED axis i (M_i total mass, kg; D_i linear damping, kg/s):
 *
 *     v_i' = (u_i - D_i v_i) / M_i                                          (m/s^2)
 *     v_i(t + h) = a_i v_i(t) + (1 - a_i) u_i / D_i,  a_i = exp(-D_i h / M_i)  (exact, u held)
 *     z_d(t + h) = z_d(t) + (u_D/D_D) h + (v_D - u_D/D_D) tau (1 - exp(-h/tau)),  tau = M_D/D_D
 *
 * Outputs at a communication point (v = v_ref, v' with the force u just set):
 *
 *     speed = |v| (m/s), course = atan2(v_E, v_N) (rad; the held course while
 *     sqrt(v_N^2 + v_E^2) <= U_min), depth = z_d (m),
 *     speed_rate = v . v' / |v| (m/s^2; 0 at |v| <= U_min),
 *     course_rate = (v_N v_E' - v_E v_N') / (v_N^2 + v_E^2) (rad/s; 0 below U_min),
 *     depth_rate = v_D (m/s), v_ref = v (m/s).
 *
 * After a step the held course becomes atan2(v_E, v_N) if hypot(v_N, v_E) > U_min. Any
 * communication step. Parameters refused at initialization: M[i] or D[i] not positive,
 * U_min negative (fmu_core.c refuses any that is not finite).
 */
#include <math.h>
#include <stdio.h>

#define NATIVE_MODEL_TABLES
#include "fmu_core.h"
#include "named_reals.h"      /* start values and names from the tables */

#if !defined(VR_M) || !defined(VR_D) || !defined(VR_v_ref0) || !defined(VR_u) || \
    !defined(VR_v_ref) || !defined(VR_speed_rate)
#error "native_model.h is not AuvGuidance's"
#endif

int model_check(Instance *in) {
    const double *r = in->d.r;
    for (int i = 0; i < 6; i++) {
        int vr = i < 3 ? VR_M + i : VR_D + i - 3;
        if (!(r[vr] > 0.0)) {
            fmu_log(in, fmi2Error, "parameter %s = %g must be a positive finite number (%s)",
                    REAL_NAMES[vr], r[vr], i < 3 ? "kg" : "kg/s");
            return -1;
        }
    }
    if (!(r[VR_U_min] >= 0.0)) {
        fmu_log(in, fmi2Error, "parameter U_min = %g m/s must not be negative", r[VR_U_min]);
        return -1;
    }
    return 0;
}

/* the course of v if the horizontal speed is above U_min, else the one held (rad); the
   speed by + * and sqrt, not hypot(), whose last bit differs between platforms' libm */
static double course_of(const double *v, double held, double U_min) {
    return sqrt(v[0] * v[0] + v[1] * v[1]) > U_min ? atan2(v[1], v[0]) : held;
}

void model_reset(Data *d) {
    ModelState *s = &d->m;
    for (int i = 0; i < 3; i++) s->v[i] = d->r[VR_v_ref0 + i];
    s->depth = d->r[VR_depth0];
    s->held = course_of(s->v, d->r[VR_course0], d->r[VR_U_min]);
}

void model_outputs(Data *d) {
    const double *M = d->r + VR_M, *D = d->r + VR_D, *u = d->r + VR_u, *v = d->m.v;
    double U_min = d->r[VR_U_min], vd[3];
    for (int i = 0; i < 3; i++) vd[i] = (u[i] - D[i] * v[i]) / M[i];
    double U = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    double h2 = v[0] * v[0] + v[1] * v[1];
    int defined = sqrt(h2) > U_min;
    d->r[VR_speed] = U;
    d->r[VR_course] = defined ? atan2(v[1], v[0]) : d->m.held;
    d->r[VR_depth] = d->m.depth;
    d->r[VR_speed_rate] = U > U_min ? (v[0] * vd[0] + v[1] * vd[1] + v[2] * vd[2]) / U : 0.0;
    d->r[VR_course_rate] = defined ? (v[0] * vd[1] - v[1] * vd[0]) / h2 : 0.0;
    d->r[VR_depth_rate] = v[2];
    for (int i = 0; i < 3; i++) d->r[VR_v_ref + i] = v[i];
}

int model_step(Instance *in, double t, double step) {
    Data *d = &in->d;
    const double *M = d->r + VR_M, *D = d->r + VR_D, *u = d->r + VR_u;
    ModelState next = d->m;
    double tau = M[2] / D[2], v_inf = u[2] / D[2];
    next.depth += v_inf * step + (d->m.v[2] - v_inf) * tau * (-expm1(-step / tau));
    for (int i = 0; i < 3; i++) {
        double a = exp(-D[i] * step / M[i]);
        next.v[i] = a * d->m.v[i] + (1.0 - a) * u[i] / D[i];
    }
    next.held = course_of(next.v, d->m.held, d->r[VR_U_min]);
    if (!isfinite(next.v[0] + next.v[1] + next.v[2] + next.depth + next.held)) {
        fmu_log(in, fmi2Error, "%s: the reference velocity or depth would become non-finite "
                "in the step from t = %g s to %g s", in->name, t, t + step);
        return -1;
    }
    d->m = next;
    return 0;
}
