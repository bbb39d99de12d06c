/*
 * The multi-rate navigation filter (estimator_fmu/multirate.py, MultiRateKalman) as a native
 * FMU on the shared FMI plumbing (fmu_core.c), in plain C99: a time-varying Kalman filter on
 * s = [x; w] (NS = NX + NR) whose gain follows the reports that arrive (acoustic fix, DVL,
 * depth, each with a valid flag). The design (Ad, Bd, Qd sampled at h, the start P0, R) is
 * the pythonfmu slave's, taken at export as parameters; the filter itself runs here:
 *
 *   rows present at k:  J = the rows of [fix (3), dvl (3), depth] whose valid flag is > 0.5
 *   H = [[I3, 0, 0], [0, I3, 0], [e_3', 0, 0]] (7 x NS; fix: position, dvl: velocity,
 *   depth: position row 3),  R = diag(Rd)
 *   est = q + K (m_J - H_J q),  K = (S^-1 H_J P)',  S = H_J P H_J' + R_J
 *         (Gaussian elimination with partial pivoting, as LAPACK's dgesv)
 *   est[w] clipped to [-current_max, current_max] per axis
 *   P+  = (I - K H_J) P (I - K H_J)' + K R_J K'                (Joseph form)
 *   q(k+1) = Ad est + Bd u,  P(k+1) = sym(Ad P+ Ad' + Qd)
 *
 * With no report, est = q and P+ = P. Outputs xhat = est[0..NX), what = est[NX..NS): direct
 * feedthrough from nav. Refused at initialization: h, a diagonal entry of R or current_max
 * not positive; a P0 or Qd that is not symmetric. A step whose state would turn non-finite
 * is refused, naming the time.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#define NATIVE_MODEL_TABLES
#include "fmu_core.h"
#include "named_reals.h"
#include "kalman_core.h"

#if !defined(NS) || !defined(VR_Ad) || !defined(VR_nav) || !defined(VR_xhat)
#error "native_model.h is not the multi-rate filter's"
#endif

#define NAVROWS 7
#define R_(vr) (d->r[(vr)])

int model_check(Instance *in) {
    const Data *d = &in->d;
    if (!(R_(VR_h) > 0.0)) {
        fmu_log(in, fmi2Error, "parameter h = %g s must be a positive number", R_(VR_h));
        return -1;
    }
    for (int i = 0; i < NAVROWS; i++) {
        if (!(R_(VR_Rd + i) > 0.0)) {
            fmu_log(in, fmi2Error, "parameter %s = %g must be a positive variance",
                    REAL_NAMES[VR_Rd + i], R_(VR_Rd + i));
            return -1;
        }
    }
    if (!(R_(VR_current_max) > 0.0)) {
        fmu_log(in, fmi2Error, "parameter current_max = %g m/s must be positive",
                R_(VR_current_max));
        return -1;
    }
    for (int a = 0; a < NS; a++) {
        for (int b = 0; b < a; b++) {
            if (R_(VR_P0 + a * NS + b) != R_(VR_P0 + b * NS + a) ||
                R_(VR_Qd + a * NS + b) != R_(VR_Qd + b * NS + a)) {
                int p = R_(VR_P0 + a * NS + b) != R_(VR_P0 + b * NS + a);
                fmu_log(in, fmi2Error, "parameter %s is not symmetric: %s differs from %s",
                        p ? "P0" : "Qd", REAL_NAMES[(p ? VR_P0 : VR_Qd) + a * NS + b],
                        REAL_NAMES[(p ? VR_P0 : VR_Qd) + b * NS + a]);
                return -1;
            }
        }
    }
    return 0;
}

void model_reset(Data *d) {
    for (int i = 0; i < NS; i++) d->m.q[i] = R_(VR_q0 + i);
    for (int i = 0; i < NS * NS; i++) d->m.P[i] = R_(VR_P0 + i);
}

/* the state index measured by navigation row j (fix: position, dvl: velocity, depth) */
static int measured(int j) { return j < 6 ? j : 2; }

/* est and P+ from q, P and the reports in nav (module comment); 0, or -1 if S is singular */
static int filter(const Data *d, double est[NS], double Pp[NS * NS]) {
    const double *nav = d->r + VR_nav, *q = d->m.q, *P = d->m.P;
    int J[NAVROWS], nj = 0;
    for (int s = 0; s < 3; s++) {
        if (!(nav[NAVROWS + s] > 0.5)) continue;
        int lo = s == 0 ? 0 : s == 1 ? 3 : 6, hi = s == 0 ? 3 : s == 1 ? 6 : 7;
        for (int j = lo; j < hi; j++) J[nj++] = j;
    }
    memcpy(est, q, sizeof(double) * NS);
    if (nj == 0) {
        memcpy(Pp, P, sizeof(double) * NS * NS);
        return 0;
    }
    double S[NAVROWS][NAVROWS], X[NAVROWS][NS], K[NS][NAVROWS], IKH[NS][NS], T[NS][NS];
    for (int a = 0; a < nj; a++) {
        for (int b = 0; b < nj; b++)
            S[a][b] = P[measured(J[a]) * NS + measured(J[b])] + (a == b ? R_(VR_Rd + J[a]) : 0.0);
        for (int c = 0; c < NS; c++) X[a][c] = P[measured(J[a]) * NS + c];   /* H P */
    }
    {                                               /* S X = H P (kalman_core.h) */
        double Sf[NAVROWS * NAVROWS], Xf[NAVROWS * NS];
        for (int a = 0; a < nj; a++) {
            for (int b = 0; b < nj; b++) Sf[a * nj + b] = S[a][b];
            for (int c = 0; c < NS; c++) Xf[a * NS + c] = X[a][c];
        }
        if (kalman_solve(nj, NS, Sf, Xf) != 0) return -1;
        for (int a = 0; a < nj; a++)
            for (int c = 0; c < NS; c++) X[a][c] = Xf[a * NS + c];
    }
    for (int a = 0; a < NS; a++)
        for (int b = 0; b < nj; b++) K[a][b] = X[b][a];
    for (int a = 0; a < NS; a++) {                  /* est = q + K (m_J - H_J q) */
        double acc = 0.0;
        for (int b = 0; b < nj; b++) acc += K[a][b] * (nav[J[b]] - q[measured(J[b])]);
        est[a] = q[a] + acc;
    }
    for (int a = NX; a < NS; a++) {
        double cm = R_(VR_current_max);
        est[a] = est[a] < -cm ? -cm : est[a] > cm ? cm : est[a];
    }
    for (int a = 0; a < NS; a++)                    /* IKH = I - K H_J */
        for (int b = 0; b < NS; b++) {
            double kh = 0.0;
            for (int c = 0; c < nj; c++) kh += measured(J[c]) == b ? K[a][c] : 0.0;
            IKH[a][b] = (a == b ? 1.0 : 0.0) - kh;
        }
    for (int a = 0; a < NS; a++)                    /* T = IKH P */
        for (int b = 0; b < NS; b++) {
            double acc = 0.0;
            for (int c = 0; c < NS; c++) acc += IKH[a][c] * P[c * NS + b];
            T[a][b] = acc;
        }
    for (int a = 0; a < NS; a++)                    /* P+ = T IKH' + (K R) K' */
        for (int b = 0; b < NS; b++) {
            double acc = 0.0, kr = 0.0;
            for (int c = 0; c < NS; c++) acc += T[a][c] * IKH[b][c];
            for (int c = 0; c < nj; c++) kr += K[a][c] * R_(VR_Rd + J[c]) * K[b][c];
            Pp[a * NS + b] = acc + kr;
        }
    return 0;
}

/* the estimate and P+ into the state's cache; the outputs from it */
void model_outputs(Data *d) {
    ModelState *m = &d->m;
    m->ok = filter(d, m->est, m->Pp) == 0;
    if (!m->ok)
        for (int i = 0; i < NS; i++) m->est[i] = NAN;   /* fmi2GetReal reports it, named */
    for (int i = 0; i < NX; i++) d->r[VR_xhat + i] = m->est[i];
    for (int i = NX; i < NS; i++) d->r[VR_what + i - NX] = m->est[i];
}

/* fmu_core.c has just computed the outputs of these inputs (model_outputs): the step goes on
   from the cached estimate and P+ */
int model_step(Instance *in, double t, double step) {
    Data *d = &in->d;
    const double *Ad = d->r + VR_Ad, *Bd = d->r + VR_Bd, *Qd = d->r + VR_Qd, *u = d->r + VR_u;
    if (!d->m.ok) {
        fmu_log(in, fmi2Error, "%s: the innovation covariance is singular at t = %g s",
                in->name, t);
        return -1;
    }
    if (kalman_predict(NS, NU_, Ad, Bd, Qd, d->m.est, d->m.Pp, u, d->m.q, d->m.P) != 0) {
        fmu_log(in, fmi2Error, "%s: the filter's state would become non-finite in the step "
                "from t = %g s to %g s", in->name, t, t + step);
        return -1;
    }
    return 0;
}
