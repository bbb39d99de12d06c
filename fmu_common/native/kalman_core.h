/*
 * What the native Kalman filters share (multirate_fmu.c: the navigation filter; tvkf_fmu.c:
 * the time-varying filter from P0), in plain C99 on row-major arrays of any size:
 *
 *   kalman_solve:    S X = B for X (nj x ns), S nj x nj, by Gaussian elimination with
 *                    partial pivoting (as LAPACK's dgesv); S and B are overwritten
 *                    (B holds X); -1 if S is singular
 *   kalman_predict:  q+ = Ad est + Bd u,  P+ = sym(Ad Pp Ad' + Qd); 0, or -1 if a value
 *                    turned non-finite (nothing written then)
 */
#ifndef KALMAN_CORE_H
#define KALMAN_CORE_H

#include <math.h>
#include <string.h>

static int kalman_solve(int nj, int ns, double *S, double *X) {
    for (int c = 0; c < nj; c++) {
        int piv = c;
        for (int a = c + 1; a < nj; a++)
            if (fabs(S[a * nj + c]) > fabs(S[piv * nj + c])) piv = a;
        if (S[piv * nj + c] == 0.0) return -1;
        if (piv != c) {
            for (int b = 0; b < nj; b++) {
                double t = S[c * nj + b]; S[c * nj + b] = S[piv * nj + b]; S[piv * nj + b] = t;
            }
            for (int b = 0; b < ns; b++) {
                double t = X[c * ns + b]; X[c * ns + b] = X[piv * ns + b]; X[piv * ns + b] = t;
            }
        }
        for (int a = c + 1; a < nj; a++) {
            double f = S[a * nj + c] / S[c * nj + c];
            for (int b = c; b < nj; b++) S[a * nj + b] -= f * S[c * nj + b];
            for (int b = 0; b < ns; b++) X[a * ns + b] -= f * X[c * ns + b];
        }
    }
    for (int c = nj - 1; c >= 0; c--) {
        for (int b = 0; b < ns; b++) {
            double v = X[c * ns + b];
            for (int a = c + 1; a < nj; a++) v -= S[c * nj + a] * X[a * ns + b];
            X[c * ns + b] = v / S[c * nj + c];
        }
    }
    return 0;
}

static int kalman_predict(int ns, int nu, const double *Ad, const double *Bd, const double *Qd,
                          const double *est, const double *Pp, const double *u,
                          double *q_out, double *P_out) {
    double q[ns], T[ns * ns], P[ns * ns];
    int ok = 1;
    for (int a = 0; a < ns; a++) {
        double acc = 0.0, bu = 0.0;
        for (int b = 0; b < ns; b++) acc += Ad[a * ns + b] * est[b];
        for (int b = 0; b < nu; b++) bu += Bd[a * nu + b] * u[b];
        q[a] = acc + bu;
        for (int b = 0; b < ns; b++) {
            double v = 0.0;
            for (int c = 0; c < ns; c++) v += Ad[a * ns + c] * Pp[c * ns + b];
            T[a * ns + b] = v;
        }
    }
    for (int a = 0; a < ns; a++)
        for (int b = 0; b < ns; b++) {
            double v = 0.0;
            for (int c = 0; c < ns; c++) v += T[a * ns + c] * Ad[b * ns + c];
            P[a * ns + b] = v + Qd[a * ns + b];
        }
    for (int a = 0; a < ns; a++)
        for (int b = 0; b < ns; b++) {
            double v = 0.5 * (P[a * ns + b] + P[b * ns + a]);
            ok = ok && isfinite(v);
            T[a * ns + b] = v;
        }
    for (int a = 0; a < ns; a++) ok = ok && isfinite(q[a]);
    if (!ok) return -1;
    memcpy(q_out, q, sizeof(double) * ns);
    memcpy(P_out, T, sizeof(double) * ns * ns);
    return 0;
}

#endif
