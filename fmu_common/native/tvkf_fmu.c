/*
 * The time-varying Kalman filter from P0 (estimator_fmu/kalman_tv.py, TimeVaryingKalman) as
 * a native FMU on the shared FMI plumbing (fmu_core.c), in plain C99, with the
 * navigation filter's state (multirate_model.h) and Kalman core (kalman_core.h). The design
 * (Ad, Bd, Qd, Rd, Mm sampled at h, P0, q0) is the pythonfmu slave's, taken at export as
 * parameters; the filter runs here:
 *
 *   meas = the first NY inputs ([y; ybar] stacked, y per vehicle)
 *   S = Mm P Mm' + Rd,  K = (S^-1 Mm P)'      (kalman_solve: elimination, pivoting)
 *   est = q + K (meas - Mm q)
 *   P+  = (I - K Mm) P (I - K Mm)' + K Rd K'   (Joseph form)
 *   q(k+1) = Ad est + Bd u,  P(k+1) = sym(Ad P+ Ad' + Qd)   (kalman_predict)
 *
 * Outputs: est, the NS outputs in order (xhat, what[, zhat]), direct feedthrough. Refused
 * at initialization: h not positive; P0, Qd or Rd not symmetric. A singular S or a state
 * turning non-finite is refused at the step, naming the time.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#define NATIVE_MODEL_TABLES
#include "fmu_core.h"
#include "named_reals.h"
#include "kalman_core.h"

#if !defined(NS) || !defined(NY) || !defined(VR_Mm) || !defined(VR_MEAS) || !defined(VR_EST)
#error "native_model.h is not the time-varying Kalman filter's"
#endif

#define R_(vr) (d->r[(vr)])

static int symmetric(Instance *in, int vr, int n, const char *name) {
    const Data *d = &in->d;
    for (int a = 0; a < n; a++)
        for (int b = 0; b < a; b++)
            if (R_(vr + a * n + b) != R_(vr + b * n + a)) {
                fmu_log(in, fmi2Error, "parameter %s is not symmetric: %s differs from %s",
                        name, REAL_NAMES[vr + a * n + b], REAL_NAMES[vr + b * n + a]);
                return -1;
            }
    return 0;
}

int model_check(Instance *in) {
    const Data *d = &in->d;
    if (!(R_(VR_h) > 0.0)) {
        fmu_log(in, fmi2Error, "parameter h = %g s must be a positive number", R_(VR_h));
        return -1;
    }
    if (symmetric(in, VR_P0, NS, "P0") || symmetric(in, VR_Qd, NS, "Qd") ||
        symmetric(in, VR_Rd, NY, "Rd"))
        return -1;
    return 0;
}

void model_reset(Data *d) {
    for (int i = 0; i < NS; i++) d->m.q[i] = R_(VR_q0 + i);
    for (int i = 0; i < NS * NS; i++) d->m.P[i] = R_(VR_P0 + i);
}

/* est and P+ from q, P and the measurements (module comment); 0, or -1 if S is singular */
static int filter(const Data *d, double est[NS], double Pp[NS * NS]) {
    const double *meas = d->r + VR_MEAS, *q = d->m.q, *P = d->m.P;
    const double *Mm = d->r + VR_Mm, *Rd = d->r + VR_Rd;
    double S[NY * NY], X[NY * NS], K[NS * NY], IKH[NS * NS], T[NS * NS];
    for (int a = 0; a < NY; a++)                    /* X = Mm P */
        for (int b = 0; b < NS; b++) {
            double v = 0.0;
            for (int c = 0; c < NS; c++) v += Mm[a * NS + c] * P[c * NS + b];
            X[a * NS + b] = v;
        }
    for (int a = 0; a < NY; a++)                    /* S = (Mm P) Mm' + Rd */
        for (int b = 0; b < NY; b++) {
            double v = 0.0;
            for (int c = 0; c < NS; c++) v += X[a * NS + c] * Mm[b * NS + c];
            S[a * NY + b] = v + Rd[a * NY + b];
        }
    if (kalman_solve(NY, NS, S, X) != 0) return -1;
    for (int a = 0; a < NS; a++)
        for (int b = 0; b < NY; b++) K[a * NY + b] = X[b * NS + a];
    for (int a = 0; a < NS; a++) {                  /* est = q + K (meas - Mm q) */
        double acc = 0.0;
        for (int b = 0; b < NY; b++) {
            double mq = 0.0;
            for (int c = 0; c < NS; c++) mq += Mm[b * NS + c] * q[c];
            acc += K[a * NY + b] * (meas[b] - mq);
        }
        est[a] = q[a] + acc;
    }
    for (int a = 0; a < NS; a++)                    /* IKH = I - K Mm */
        for (int b = 0; b < NS; b++) {
            double kh = 0.0;
            for (int c = 0; c < NY; c++) kh += K[a * NY + c] * Mm[c * NS + b];
            IKH[a * NS + b] = (a == b ? 1.0 : 0.0) - kh;
        }
    for (int a = 0; a < NS; a++)                    /* T = IKH P */
        for (int b = 0; b < NS; b++) {
            double acc = 0.0;
            for (int c = 0; c < NS; c++) acc += IKH[a * NS + c] * P[c * NS + b];
            T[a * NS + b] = acc;
        }
    for (int a = 0; a < NS; a++)                    /* P+ = T IKH' + K Rd K' */
        for (int b = 0; b < NS; b++) {
            double acc = 0.0, kr = 0.0;
            for (int c = 0; c < NS; c++) acc += T[a * NS + c] * IKH[b * NS + c];
            for (int c = 0; c < NY; c++) {
                double v = 0.0;
                for (int e = 0; e < NY; e++) v += K[a * NY + e] * Rd[e * NY + c];
                kr += v * K[b * NY + c];
            }
            Pp[a * NS + b] = acc + kr;
        }
    return 0;
}

void model_outputs(Data *d) {
    ModelState *m = &d->m;
    m->ok = filter(d, m->est, m->Pp) == 0;
    for (int i = 0; i < NS; i++) d->r[VR_EST + i] = m->ok ? m->est[i] : NAN;
}

int model_step(Instance *in, double t, double step) {
    Data *d = &in->d;
    if (!d->m.ok) {
        fmu_log(in, fmi2Error, "%s: the innovation covariance is singular at t = %g s",
                in->name, t);
        return -1;
    }
    if (kalman_predict(NS, NU_, d->r + VR_Ad, d->r + VR_Bd, d->r + VR_Qd, d->m.est, d->m.Pp,
                       d->r + VR_u, d->m.q, d->m.P) != 0) {
        fmu_log(in, fmi2Error, "%s: the filter's state would become non-finite in the step "
                "from t = %g s to %g s", in->name, t, t + step);
        return -1;
    }
    return 0;
}
