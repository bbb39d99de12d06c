/*
 * AuvAutopilot as a native FMU on the shared FMI plumbing (fmu_core.c), in plain C99: the
 * speed, course and depth set-points (and their rates) and the vehicle's measured velocity
 * through the water (body axes), attitude, body rates and depth in; propeller rpm, rudder
 * and stern-plane commands out, clipped to the limits, with anti-windup. The same
 * mathematics as plant_model/remus100/setpoint_autopilot.py and the same interface as the
 * pythonfmu AuvAutopilot (plant_model/remus100/auv_autopilot_slave.py: the generated
 * native_model.h is made from its modelDescription), so a host can swap one for the other.
 *
 * With v_w = R(phi, theta, psi) [u, v, w] the measured velocity through the water in NED
 * (m/s), U = |v_w|, chi = atan2(v_wE, v_wN) and gamma = atan2(-v_wD, |v_wh|) (psi and theta
 * at or below U_min), the integrals I = [int (U_d - U) dt (m), int (gamma_d - gamma) dt]:
 *
 *     n       = n_max U_d / U_max + K_u (U_d - U) + K_ui I_1                     (rpm)
 *     delta_r = K_chi wrap(chi_d - chi) + K_r (chi_d' - r)                        (rad)
 *     w_d     = z_d' + K_z (z_d - z),  U_h = sqrt(max(U_d^2 - z_d'^2, 0))          (m/s)
 *     gamma_d = clip(atan2(-w_d, U_h), -gamma_max, gamma_max)  (0 at U_d <= U_min) (rad)
 *     theta_d = gamma_d + K_gamma (gamma_d - gamma) + K_gi I_2                     (rad)
 *     delta_s = K_theta (theta - theta_d) + K_q q                   (rad; + nose down)
 *
 * wrap(a) = (a + pi) mod 2 pi - pi, mod as Python's (the sign of the divisor). Outputs:
 * rpm, rudder, stern clipped to +-n_max, +-delta_max; saturated = 1 if any unclipped
 * command is at or beyond its limit. A step of h: I += h [e_u, e_g], e_u = U_d - U and
 * e_g = gamma_d - gamma, each 0 while its actuator is at its limit in the direction the
 * error pushes (anti-windup by conditional integration). Any communication step.
 * Parameters refused at initialization: n_max, delta_max, U_max or gamma_max not positive.
 */
#include <math.h>
#include <stdio.h>

#define NATIVE_MODEL_TABLES
#include "fmu_core.h"
#include "named_reals.h"      /* start values and names from the tables */

#if !defined(VR_n_max) || !defined(VR_velocity) || !defined(VR_measured_depth) || \
    !defined(VR_rpm) || !defined(VR_saturated) || !defined(VR_gamma_max)
#error "native_model.h is not AuvAutopilot's"
#endif

#define PI_ 3.141592653589793

int model_check(Instance *in) {
    static const int positive[] = {VR_n_max, VR_delta_max, VR_U_max, VR_gamma_max};
    for (int i = 0; i < 4; i++) {
        double v = in->d.r[positive[i]];
        if (!(v > 0.0)) {
            fmu_log(in, fmi2Error, "parameter %s = %g must be positive",
                    REAL_NAMES[positive[i]], v);
            return -1;
        }
    }
    return 0;
}

void model_reset(Data *d) { d->m.integrals[0] = d->m.integrals[1] = 0.0; }

/* an angle in [-pi, pi): (a + pi) % (2 pi) - pi with Python's float modulo */
static double wrap(double a) {
    double x = a + PI_, y = 2.0 * PI_, m = fmod(x, y);
    if (m != 0.0) {
        if ((y < 0.0) != (m < 0.0)) m += y;
    } else {
        m = copysign(0.0, y);
    }
    return m - PI_;
}

static double clip(double x, double lim) { return fmin(fmax(x, -lim), lim); }

/* the unclipped command [delta_r, delta_s (rad), n (rpm)] and the errors to integrate */
static void command(const Data *d, double cmd[3], double err[2]) {
    const double *r = d->r, *nu = r + VR_velocity, *att = r + VR_attitude, *w = r + VR_rates;
    const double *I = d->m.integrals;
    double U_d = r[VR_speed], chi_d = r[VR_course], z_d = r[VR_depth];
    double chi_rate = r[VR_course_rate], z_rate = r[VR_depth_rate];
    double U_min = r[VR_U_min], n_max = r[VR_n_max], dmax = r[VR_delta_max];
    double cf = cos(att[0]), sf = sin(att[0]), ct = cos(att[1]), st = sin(att[1]);
    double cp = cos(att[2]), sp = sin(att[2]);
    double R[3][3] = {{cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st},
                      {sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf},
                      {-st, ct * sf, ct * cf}};
    double vw[3];
    for (int i = 0; i < 3; i++) vw[i] = R[i][0] * nu[0] + R[i][1] * nu[1] + R[i][2] * nu[2];
    double U = sqrt(vw[0] * vw[0] + vw[1] * vw[1] + vw[2] * vw[2]);
    /* not hypot(): libm's differs by an ulp between platforms (glibc x86-64 and aarch64,
       MinGW); + * and sqrt are IEEE, the same everywhere (docs/native.md) */
    double h = sqrt(vw[0] * vw[0] + vw[1] * vw[1]);
    double n = n_max * U_d / r[VR_U_max] + r[VR_K_u] * (U_d - U) + r[VR_K_ui] * I[0];
    double chi = h > U_min ? atan2(vw[1], vw[0]) : att[2];
    double delta_r = r[VR_K_chi] * wrap(chi_d - chi) + r[VR_K_r] * (chi_rate - w[2]);
    double gamma_d = 0.0;
    if (U_d > U_min) {
        double w_d = z_rate + r[VR_K_z] * (z_d - r[VR_measured_depth]);
        double U_h = sqrt(fmax(U_d * U_d - z_rate * z_rate, 0.0));
        gamma_d = fmin(fmax(atan2(-w_d, U_h), -r[VR_gamma_max]), r[VR_gamma_max]);
    }
    double gamma = U > U_min ? atan2(-vw[2], h) : att[1];
    double theta_d = gamma_d + r[VR_K_gamma] * (gamma_d - gamma) + r[VR_K_gi] * I[1];
    double delta_s = r[VR_K_theta] * (att[1] - theta_d) + r[VR_K_q] * w[1];
    err[0] = (n >= n_max && U_d > U) || (n <= -n_max && U_d < U) ? 0.0 : U_d - U;
    err[1] = gamma_d - gamma;
    if ((delta_s >= dmax && err[1] < 0.0) || (delta_s <= -dmax && err[1] > 0.0)) err[1] = 0.0;
    cmd[0] = delta_r;
    cmd[1] = delta_s;
    cmd[2] = n;
}

void model_outputs(Data *d) {
    double cmd[3], err[2], dmax = d->r[VR_delta_max], n_max = d->r[VR_n_max];
    command(d, cmd, err);
    d->r[VR_rpm] = clip(cmd[2], n_max);
    d->r[VR_rudder] = clip(cmd[0], dmax);
    d->r[VR_stern] = clip(cmd[1], dmax);
    d->r[VR_saturated] = fabs(cmd[0]) >= dmax || fabs(cmd[1]) >= dmax || fabs(cmd[2]) >= n_max
                         ? 1.0 : 0.0;
}

int model_step(Instance *in, double t, double step) {
    double cmd[3], err[2], next[2];
    command(&in->d, cmd, err);
    for (int i = 0; i < 2; i++) next[i] = in->d.m.integrals[i] + err[i] * step;
    if (!isfinite(next[0]) || !isfinite(next[1])) {
        fmu_log(in, fmi2Error, "%s: integral %d would become non-finite in the step from "
                "t = %g s to %g s", in->name, isfinite(next[0]) ? 2 : 1, t, t + step);
        return -1;
    }
    in->d.m.integrals[0] = next[0];
    in->d.m.integrals[1] = next[1];
    return 0;
}
