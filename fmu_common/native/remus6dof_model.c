/*
 * The nonlinear 6-DOF REMUS 100 in plain C99 (remus6dof_model.h): a statement-by-statement
 * translation of plant_model/remus100/kernel.py (the numba kernel) and of the stepping,
 * noise and sensor logic of plant_model/remus100/plant.py and plant_model/navigation.py.
 *
 * Equations (kernel.derivative; state x = [eta; nu; delta_r, delta_s, n], current v_c):
 *
 *     nu_r = nu - [R(Theta)' v_c; 0]
 *     M nu_r' = tau_prop + tau_fins + tau_crossflow + tau_lift + tau_munk
 *               - C(nu_r) nu_r - D_lin(U_r) nu_r - g(eta)                          (N, N m)
 *     nu' = M^-1 (...) + [-omega x (R' v_c); 0],   eta' = J(eta) nu
 *     delta' = clip((clip(cmd, -lim, lim) - delta) / tau, -lim / tau, lim / tau)
 *
 * thrust = rho D^4 KT n|n| (n in rps, KT linear in J_a = 0.944 U / (n D)), torque scaled by
 * 0.1; fins 1/2 rho U^2 A CL delta at x = -L/2; strip-theory cross-flow drag
 * -1/2 rho Cd diam dx |v + x r| (v + x r) per strip; hull lift CL_alpha alpha and drag
 * CD0 + CL^2 / (pi e AR) at alpha = atan2(w_r, u_r); linear damping fading as exp(-3 U_r)
 * in surge and sway. Classical RK4 over h / substeps, command and current held.
 *
 * A step of AuvRemus6dof (kernel.force_commanded_step, plant_step): the autopilot command
 * from the state (speed, course, flight-path loops, anti-windup), RK4, the integrals
 * I += h e, v_ref <- a v_ref + (1 - a) F / D with a = exp(-D h / M); then the process
 * noise p += v_x[0:3], nu[0:3] += R' v_x[3:6] and the current w <- Aw w + v_w
 * (kernel._disturb). AuvRemus6dofActuated (kernel.actuated_step) takes the command
 * [n, delta_r, delta_s] instead. The noise row of sample k is P xi_k, xi_k 15 ziggurat
 * normals of numpy's default_rng([seed, vehicle]) (plant_model.plant.NoiseStream); the
 * sensors draw 1024 x 7 normals then 1024 x 3 uniforms from default_rng([seed,
 * 3000000 + vehicle]) per block (plant_model.navigation.SensorStream).
 *
 * The order of the floating-point operations is the Python kernel's: C and Python group
 * a * b * c and a - b + c the same way (left to right), x ** 4 is (x x)(x x) as numba's
 * integer power, and no contraction to fused multiply-adds (-std=c99 turns it off).
 */
#include <math.h>
#include <string.h>

#include "remus6dof_model.h"

/* the parameter vector layout of kernel.pack */
enum {
    P_M = 0, P_MINV = 36, P_MA = 72, P_LIN = 78, P_W = 84, P_RG = 85, P_LIM = 88, P_TAU = 91,
    P_RHO = 94, P_L = 95, P_ARUD = 96, P_ASTE = 97, P_TD = 98, P_WAKE = 99, P_DPROP = 100,
    P_KT0 = 101, P_KQ0 = 102, P_KTS = 103, P_KQS = 104, P_S = 105, P_CLA = 106, P_CDI = 107,
    P_CD0 = 108, P_SK = 109, P_NS = 110, P_TQS = 111, P_CFV = 112, P_SX = 113
};

#define PI_ 3.141592653589793
#define SENSOR_STREAM_KEY 3000000u

/* min(max(a, lo), hi) as Python's builtins: max(a, lo) is a unless lo > a */
static double py_clip(double a, double lo, double hi) {
    double m = lo > a ? lo : a;
    return hi < m ? hi : m;
}

/* R(Theta), body to NED (zyx), row major: kernel._rotation */
static void rotation(double phi, double theta, double psi, double R[9]) {
    double cf = cos(phi), sf = sin(phi), ct = cos(theta), st = sin(theta);
    double cp = cos(psi), sp = sin(psi);
    R[0] = cp * ct; R[1] = -sp * cf + cp * st * sf; R[2] = sp * sf + cp * cf * st;
    R[3] = sp * ct; R[4] = cp * cf + sf * st * sp; R[5] = -cp * sf + st * sp * cf;
    R[6] = -st; R[7] = ct * sf; R[8] = ct * cf;
}

void remus_derivative(const double *p, const double *x, const double *cmd, const double *cur,
                      double *out) {
    double phi = x[3], theta = x[4];
    double cf = cos(phi), sf = sin(phi), ct = cos(theta), st = sin(theta);
    double R[9];
    rotation(phi, theta, x[5], R);
    double c0 = cur[0], c1 = cur[1], c2 = cur[2];
    double vb0 = R[0] * c0 + R[3] * c1 + R[6] * c2;              /* R' v_c */
    double vb1 = R[1] * c0 + R[4] * c1 + R[7] * c2;
    double vb2 = R[2] * c0 + R[5] * c1 + R[8] * c2;
    double u = x[6], v = x[7], w = x[8], pr = x[9], q = x[10], r = x[11];
    double nr[6] = {u - vb0, v - vb1, w - vb2, pr, q, r};
    double ur = nr[0], vr = nr[1], wr = nr[2];
    double U_r = sqrt(ur * ur + vr * vr + wr * wr);
    double U = sqrt(u * u + v * v + w * w);
    double dm = p[P_LIM], nmax = p[P_LIM + 2];
    double dr = py_clip(x[12], -dm, dm), ds = py_clip(x[13], -dm, dm);
    double n_rpm = py_clip(x[14], -nmax, nmax);
    double rho = p[P_RHO];
    /* propeller */
    double n = n_rpm / 60.0, KTn, KQn;
    if (n > 0.0) {
        double Ja_n = p[P_WAKE] * U / p[P_DPROP];
        KTn = p[P_KT0] * n * n + p[P_KTS] * Ja_n * n;
        KQn = p[P_KQ0] * n * n + p[P_KQS] * Ja_n * n;
    } else {
        KTn = p[P_KT0] * fabs(n) * n;
        KQn = p[P_KQ0] * fabs(n) * n;
    }
    double D2 = p[P_DPROP] * p[P_DPROP], D4 = D2 * D2;         /* numba's x ** 4 */
    double thrust = rho * D4 * KTn, torque = p[P_TQS] * rho * D4 * p[P_DPROP] * KQn;
    /* fins */
    double U_h2 = ur * ur + vr * vr, U_v2 = ur * ur + wr * wr;
    double Yr = -0.5 * rho * U_h2 * p[P_ARUD] * dr;
    double Zs = -0.5 * rho * U_v2 * p[P_ASTE] * ds;
    double x_tail = -p[P_L] / 2.0;
    double f[6];
    f[0] = ((1.0 - p[P_TD]) * thrust
            - 0.5 * rho * (U_h2 * p[P_ARUD] * dr * dr + U_v2 * p[P_ASTE] * ds * ds));
    f[1] = Yr; f[2] = Zs; f[3] = torque; f[4] = -x_tail * Zs; f[5] = x_tail * Yr;
    /* strip-theory cross-flow drag */
    double k = p[P_SK], Fy = 0.0, Fz = 0.0, My = 0.0, Mz = 0.0;
    int ns = (int)p[P_NS];
    for (int i = 0; i < ns; i++) {
        double xs = p[P_SX + i];
        double vy = vr + xs * r, vz = wr - xs * q;
        double fy = -k * fabs(vy) * vy, fz = -p[P_CFV] * k * fabs(vz) * vz;
        Fy += fy;
        Fz += fz;
        My += xs * fz;
        Mz += xs * fy;
    }
    f[1] += Fy;
    f[2] += Fz;
    f[4] -= My;
    f[5] += Mz;
    /* hull lift and drag in the vertical plane */
    if (ur * ur + wr * wr != 0.0) {
        double alpha = atan2(wr, ur);
        double CL = p[P_CLA] * alpha;
        double CD = p[P_CD0] + CL * CL * p[P_CDI];
        double qd = 0.5 * rho * (ur * ur + vr * vr + wr * wr) * p[P_S];
        double drag = qd * CD, lift = qd * CL;
        double ca = cos(alpha), sa = sin(alpha);
        f[0] += -ca * drag + sa * lift;
        f[2] += -sa * drag - ca * lift;
    }
    /* the C_A entries the reference removes, added back (dynamics._munk_balance) */
    double Xa = p[P_MA], Ya = p[P_MA + 1], Za = p[P_MA + 2];
    f[0] += Za * wr * q - Ya * vr * r;
    f[1] += Xa * ur * r;
    f[2] -= Xa * ur * q;
    f[4] += (Xa - Za) * ur * wr;
    f[5] += (Ya - Xa) * ur * vr;
    /* Coriolis C(nu_r) nu_r = [nu2 x a; nu1 x a + nu2 x b], [a; b] = M nu_r */
    double ab[6];
    for (int i = 0; i < 6; i++) {
        double s = 0.0;
        for (int j = 0; j < 6; j++) s += p[P_M + 6 * i + j] * nr[j];
        ab[i] = s;
    }
    double a0 = ab[0], a1 = ab[1], a2 = ab[2], b0 = ab[3], b1 = ab[4], b2 = ab[5];
    f[0] -= q * a2 - r * a1;
    f[1] -= r * a0 - pr * a2;
    f[2] -= pr * a1 - q * a0;
    f[3] -= vr * a2 - wr * a1 + q * b2 - r * b1;
    f[4] -= wr * a0 - ur * a2 + r * b0 - pr * b2;
    f[5] -= ur * a1 - vr * a0 + pr * b1 - q * b0;
    /* linear damping, fading with speed in surge and sway */
    double fade = exp(-3.0 * U_r);
    for (int i = 0; i < 6; i++) {
        double li = p[P_LIN + i];
        if (i == 0 || i == 1) li *= fade;
        f[i] -= li * nr[i];
    }
    /* restoring forces (W = B, CB at CO) */
    double W = p[P_W], xg = p[P_RG], yg = p[P_RG + 1], zg = p[P_RG + 2];
    f[3] -= -(yg * W) * ct * cf + (zg * W) * ct * sf;
    f[4] -= (zg * W) * st + (xg * W) * ct * cf;
    f[5] -= -(xg * W) * ct * sf - (yg * W) * st;
    /* kinematics */
    out[0] = R[0] * u + R[1] * v + R[2] * w;
    out[1] = R[3] * u + R[4] * v + R[5] * w;
    out[2] = R[6] * u + R[7] * v + R[8] * w;
    double tt = st / ct;
    out[3] = pr + sf * tt * q + cf * tt * r;
    out[4] = cf * q - sf * r;
    out[5] = sf / ct * q + cf / ct * r;
    /* nu' = nu_c' + M^-1 force, nu_c' = [-omega x (R' v_c); 0] */
    double ncd0 = -(q * vb2 - r * vb1), ncd1 = -(r * vb0 - pr * vb2), ncd2 = -(pr * vb1 - q * vb0);
    for (int i = 0; i < 6; i++) {
        double s = 0.0;
        for (int j = 0; j < 6; j++) s += p[P_MINV + 6 * i + j] * f[j];
        out[6 + i] = s;
    }
    out[6] += ncd0;
    out[7] += ncd1;
    out[8] += ncd2;
    /* actuators: first-order lag to the saturated command, rate limited */
    for (int i = 0; i < 3; i++) {
        double lim = p[P_LIM + i], tau = p[P_TAU + i];
        double target = py_clip(cmd[i], -lim, lim);
        out[12 + i] = py_clip((target - x[12 + i]) / tau, -lim / tau, lim / tau);
    }
}

void remus_rk4(const double *p, double *x, const double *cmd, const double *cur, double dt,
               int substeps) {
    double k1[REMUS_NX], k2[REMUS_NX], k3[REMUS_NX], k4[REMUS_NX], y[REMUS_NX];
    for (int s = 0; s < substeps; s++) {
        remus_derivative(p, x, cmd, cur, k1);
        for (int i = 0; i < REMUS_NX; i++) y[i] = x[i] + 0.5 * dt * k1[i];
        remus_derivative(p, y, cmd, cur, k2);
        for (int i = 0; i < REMUS_NX; i++) y[i] = x[i] + 0.5 * dt * k2[i];
        remus_derivative(p, y, cmd, cur, k3);
        for (int i = 0; i < REMUS_NX; i++) y[i] = x[i] + dt * k3[i];
        remus_derivative(p, y, cmd, cur, k4);
        for (int i = 0; i < REMUS_NX; i++)
            x[i] = x[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
}

/* (a + pi) % (2 pi) - pi with Python's float modulo (the sign of the divisor) */
static double wrap(double a) {
    double xx = a + PI_, y = 2.0 * PI_, m = fmod(xx, y);
    if (m != 0.0) {
        if ((y < 0.0) != (m < 0.0)) m += y;
    } else {
        m = copysign(0.0, y);
    }
    return m - PI_;
}

/* kernel.autopilot: cmd = [delta_r, delta_s, n], err = [U_d - U, gamma_d - gamma] */
static void autopilot(const double *g, const double *x, const double *v_ref, const double *integ,
                      const double *cur, double *cmd, double *err) {
    double U_max = g[0], n_max = g[1], K_u = g[2], K_ui = g[3], K_chi = g[4], K_r = g[5];
    double K_gamma = g[6], K_gi = g[7], K_theta = g[8], K_q = g[9], U_min = g[10];
    double theta = x[4], psi = x[5], R[9];
    rotation(x[3], theta, psi, R);
    double u = x[6], v = x[7], w = x[8];
    double g0 = R[0] * u + R[1] * v + R[2] * w - cur[0];       /* over ground, less current */
    double g1 = R[3] * u + R[4] * v + R[5] * w - cur[1];
    double g2 = R[6] * u + R[7] * v + R[8] * w - cur[2];
    double U = sqrt(g0 * g0 + g1 * g1 + g2 * g2);
    double U_d = sqrt(v_ref[0] * v_ref[0] + v_ref[1] * v_ref[1] + v_ref[2] * v_ref[2]);
    cmd[2] = n_max * U_d / U_max + K_u * (U_d - U) + K_ui * integ[0];
    double h_ref = hypot(v_ref[0], v_ref[1]);
    double chi_d = h_ref > U_min ? atan2(v_ref[1], v_ref[0]) : psi;
    double h_g = hypot(g0, g1);
    double chi = h_g > U_min ? atan2(g1, g0) : psi;
    cmd[0] = K_chi * wrap(chi_d - chi) - K_r * x[11];
    double gamma_d = U_d > U_min ? atan2(-v_ref[2], h_ref) : 0.0;
    double gamma = U > U_min ? atan2(-g2, h_g) : theta;
    double theta_d = gamma_d + K_gamma * (gamma_d - gamma) + K_gi * integ[1];
    cmd[1] = K_theta * (theta - theta_d) + K_q * x[10];
    double dmax = g[11], e_u = U_d - U, e_g = gamma_d - gamma;
    if ((cmd[2] >= n_max && U_d > U) || (cmd[2] <= -n_max && U_d < U)) e_u = 0.0;
    if ((cmd[1] >= dmax && e_g < 0.0) || (cmd[1] <= -dmax && e_g > 0.0)) e_g = 0.0;
    err[0] = e_u;
    err[1] = e_g;
}

static double saturation(const double *cmd, const double *limits) {
    double sat = 0.0;
    for (int i = 0; i < 3; i++)
        if (fabs(cmd[i]) >= limits[i]) sat = 1.0;
    return sat;
}

/* kernel._disturb: p += v[0:3], nu[0:3] += R' v[3:6], w <- Aw w + v[6:9] */
static void disturb(double *x, double *w, const double *v, const double *Aw) {
    for (int i = 0; i < 3; i++) x[i] += v[i];
    double R[9];
    rotation(x[3], x[4], x[5], R);
    double a = v[3], b = v[4], c = v[5];
    x[6] += R[0] * a + R[3] * b + R[6] * c;
    x[7] += R[1] * a + R[4] * b + R[7] * c;
    x[8] += R[2] * a + R[5] * b + R[8] * c;
    double w0 = w[0], w1 = w[1], w2 = w[2];
    for (int i = 0; i < 3; i++)
        w[i] = Aw[3 * i] * w0 + Aw[3 * i + 1] * w1 + Aw[3 * i + 2] * w2 + v[6 + i];
}

/* ------------------------------------------------------------------ noise and sensors */
static void next_row(const RemusConst *c, RemusState *st) {
    double xi[REMUS_NOISE];
    for (int j = 0; j < REMUS_NOISE; j++) xi[j] = npr_standard_normal(&st->rng);
    for (int i = 0; i < REMUS_NOISE; i++) {
        double acc = 0.0;
        for (int j = 0; j < REMUS_NOISE; j++) acc += xi[j] * c->P[REMUS_NOISE * i + j];
        st->row[i] = acc;
    }
}

/* SensorStream.measure(k, p, v) on the outputs o (p = o[3:6], v = o[6:9]) */
static void measure(const RemusConst *c, RemusState *st, const double *o) {
    if (st->nav_i == REMUS_NAV_BLOCK) {
        for (int i = 0; i < REMUS_NAV_BLOCK * 7; i++)
            st->nav_normal[i] = npr_standard_normal(&st->nav_rng);
        for (int i = 0; i < REMUS_NAV_BLOCK * 3; i++)
            st->nav_uniform[i] = npr_next_double(&st->nav_rng);
        st->nav_i = 0;
    }
    const double *nn = st->nav_normal + 7 * st->nav_i, *r = st->nav_uniform + 3 * st->nav_i;
    st->nav_i += 1;
    int due[3];
    for (int j = 0; j < 3; j++) {
        due[j] = st->k % c->nav_period[j] == 0 && r[j] >= c->nav_drop[j];
        st->nav[7 + j] = due[j] ? 1.0 : 0.0;
    }
    if (due[0])
        for (int j = 0; j < 3; j++) st->nav[j] = o[3 + j] + c->nav_sigma[j] * nn[j];
    if (due[1])
        for (int j = 0; j < 3; j++) st->nav[3 + j] = o[6 + j] + c->nav_sigma[3 + j] * nn[3 + j];
    if (due[2]) st->nav[6] = o[5] + c->nav_sigma[6] * nn[6];
}

/* ------------------------------------------------------------------ the vehicle */
/* the outputs, the sensors' last with nav != 0 */
static void outputs(const RemusConst *c, const RemusState *st, double *o, int nav) {
    const double *s = st->s;
    double R[9];
    rotation(s[3], s[4], s[5], R);
    double u = s[6], v = s[7], w = s[8];
    for (int i = 0; i < 3; i++) {
        o[i] = s[i] + st->row[9 + i];
        o[3 + i] = s[i];
        o[9 + i] = s[20 + i];
        o[12 + i] = s[3 + i];
    }
    o[6] = R[0] * u + R[1] * v + R[2] * w;
    o[7] = R[3] * u + R[4] * v + R[5] * w;
    o[8] = R[6] * u + R[7] * v + R[8] * w;
    o[15] = s[14]; o[16] = s[12]; o[17] = s[13]; o[18] = st->saturated;
    int n = REMUS_OUT_FORCE;
    if (c->actuated) {                          /* kernel.actuated_outputs */
        double c0 = s[20], c1 = s[21], c2 = s[22];
        o[19] = s[6] - (R[0] * c0 + R[3] * c1 + R[6] * c2);
        o[20] = s[7] - (R[1] * c0 + R[4] * c1 + R[7] * c2);
        o[21] = s[8] - (R[2] * c0 + R[5] * c1 + R[8] * c2);
        o[22] = s[9]; o[23] = s[10]; o[24] = s[11];
        o[25] = s[2];
        n = REMUS_OUT_ACTUATED;
    }
    if (nav && c->sensors) memcpy(o + n, st->nav, sizeof st->nav);
}

void remus_outputs(const RemusConst *c, const RemusState *st, double *o) {
    outputs(c, st, o, 1);
}

/* the plant's outputs and the sensors' draw of sample k (Remus6dofPlant._outputs, _measure) */
static void sample(const RemusConst *c, RemusState *st) {
    if (!c->sensors) return;
    double o[REMUS_OUT_ACTUATED + REMUS_NAV];
    outputs(c, st, o, 0);
    measure(c, st, o);
}

void remus_reset(const RemusConst *c, RemusState *st, const double *x0, const double *w0,
                 uint32_t seed, uint32_t vehicle) {
    memset(st, 0, sizeof *st);
    double *x = st->s;
    const double *g = c->g;
    for (int i = 0; i < 3; i++) x[i] = x0[i];
    double vw[3] = {x0[3] - w0[0], x0[4] - w0[1], x0[5] - w0[2]};
    double U = sqrt(vw[0] * vw[0] + vw[1] * vw[1] + vw[2] * vw[2]);   /* numpy's norm */
    if (U > g[10]) {                            /* plant.initial_state */
        x[5] = atan2(vw[1], vw[0]);
        x[4] = atan2(-vw[2], hypot(vw[0], vw[1]));
    }
    double R[9];
    rotation(0.0, x[4], x[5], R);
    for (int i = 0; i < 3; i++) x[6 + i] = R[i] * x0[3] + R[3 + i] * x0[4] + R[6 + i] * x0[5];
    double n0 = g[1] * U / g[0];
    x[14] = c->p[P_LIM + 2] <= n0 ? c->p[P_LIM + 2] : n0;           /* min(n_max, .) */
    for (int i = 0; i < 3; i++) {
        x[15 + i] = vw[i];
        x[20 + i] = w0[i];
    }
    uint64_t e1[2] = {seed, vehicle}, e2[2] = {seed, SENSOR_STREAM_KEY + (uint64_t)vehicle};
    npr_seed(&st->rng, e1, 2);
    npr_seed(&st->nav_rng, e2, 2);
    st->nav_i = REMUS_NAV_BLOCK;
    next_row(c, st);
    sample(c, st);
}

int remus_step(const RemusConst *c, RemusState *st, const double *input) {
    double s[REMUS_NS], cmd[3], sat;
    memcpy(s, st->s, sizeof s);
    double *x = s, *w = s + 20;
    const double *v = st->row;
    if (c->actuated) {                          /* kernel.actuated_step */
        cmd[0] = input[1]; cmd[1] = input[2]; cmd[2] = input[0];
        sat = saturation(cmd, c->limits);
        remus_rk4(c->p, x, cmd, w, c->h / c->substeps, c->substeps);
    } else {                                    /* kernel.plant_step */
        double err[2], *v_ref = s + 15, *integ = s + 18;
        autopilot(c->g, x, v_ref, integ, w, cmd, err);
        remus_rk4(c->p, x, cmd, w, c->h / c->substeps, c->substeps);
        integ[0] += err[0] * c->h;
        integ[1] += err[1] * c->h;
        for (int i = 0; i < 3; i++) {
            double a = exp(-c->D[i] * c->h / c->M[i]);
            v_ref[i] = a * v_ref[i] + (1.0 - a) * input[i] / c->D[i];
        }
        sat = saturation(cmd, c->limits);
    }
    disturb(x, w, v, c->Aw);
    for (int i = 0; i < REMUS_NS; i++)
        if (!isfinite(s[i])) return -1;
    memcpy(st->s, s, sizeof s);
    memcpy(st->cmd, cmd, sizeof cmd);
    st->saturated = sat;
    st->k += 1;
    next_row(c, st);
    sample(c, st);
    return 0;
}
