/*
 * The nonlinear 6-DOF REMUS 100 in plain C99 (libc and libm only): the equations, RK4
 * sub-steps, autopilot, process noise and navigation sensors of the pythonfmu vehicles
 * AuvRemus6dof and AuvRemus6dofActuated (plant_model/remus100/kernel.py, plant.py;
 * plant_model/navigation.py), statement by statement in the same order of operations, so
 * the same seed gives the same traces (docs/native.md states the bound).
 *
 * Model source: T. I. Fossen, Python Vehicle Simulator, vehicles/remus100.py of
 * 2025-01-15 (commit 7e1db8e) with lib/gnc.py, and Fossen, Handbook of Marine Craft
 * Hydrodynamics and Motion Control, 2nd ed., Wiley 2021, section 8.4.2, with the
 * deliberate differences of plant_model/remus100/dynamics.py (docs/remus100-6dof.md).
 *
 * Units: m, s, rad, N, N m; the propeller in rpm. The evolving vector s (23) is the
 * Python plant's: [eta (6); nu (6); delta_r, delta_s (rad), n (rpm); v_ref (3, m/s);
 * integrals (2: m, rad s); w (3, the ocean current, NED, m/s)].
 */
#ifndef REMUS6DOF_MODEL_H
#define REMUS6DOF_MODEL_H

#include <stdint.h>

#include "numpy_random.h"

#define REMUS_NX 15           /* the 6-DOF state x */
#define REMUS_NS 23           /* the evolving vector s */
#define REMUS_NP_MAX 134      /* the parameter vector: P_SX + up to 21 strips (kernel.pack) */
#define REMUS_NOISE 15        /* the noise row [v_x (6); v_w (3); n (3); n_bar (3)] */
#define REMUS_NAV 10          /* [fix (3), dvl (3), depth, valid (3)] */
#define REMUS_NAV_BLOCK 1024  /* the sensors draw 1024 x 7 normals, then 1024 x 3 uniforms */
#define REMUS_OUT_FORCE 19    /* outputs of AuvRemus6dof before nav */
#define REMUS_OUT_ACTUATED 26 /* outputs of AuvRemus6dofActuated before nav */

/* what a step needs that does not evolve (derived from the FMU's parameters) */
typedef struct {
    double p[REMUS_NP_MAX];   /* kernel.pack(Remus100): layout P_* of kernel.py */
    double g[12];             /* kernel.pack_gains: U_max, n_max, K_u, K_ui, K_chi, K_r,
                                 K_gamma, K_gi, K_theta, K_q, U_min, delta_max */
    double M[3], D[3];        /* force interface per NED axis, kg and kg/s */
    double Aw[9];             /* current transition exp(K h), row major */
    double P[REMUS_NOISE * REMUS_NOISE];  /* noise row = P xi (row major) */
    double limits[3];         /* delta_max, delta_max (rad), n_max (rpm) */
    double h;                 /* communication step, s */
    int substeps;             /* RK4 sub-steps per step */
    int actuated;             /* 1: AuvRemus6dofActuated (commands in), 0: force in */
    int sensors;              /* 1: navigation sensors */
    int64_t nav_period[3];    /* fix, dvl, depth periods in steps */
    double nav_sigma[7], nav_drop[3];
} RemusConst;

/* everything that evolves: copied whole as (part of) the FMU state */
typedef struct {
    double s[REMUS_NS];
    double cmd[3];            /* the last step's command [delta_r, delta_s, n] */
    double saturated;
    double row[REMUS_NOISE];  /* the noise row of sample k */
    int64_t k;
    NprPcg64 rng;             /* default_rng([seed, vehicle]) */
    NprPcg64 nav_rng;         /* default_rng([seed, 3000000 + vehicle]) */
    int nav_i;                /* rows of the sensor block used */
    double nav_normal[REMUS_NAV_BLOCK * 7], nav_uniform[REMUS_NAV_BLOCK * 3];
    double nav[REMUS_NAV];    /* the sensors' outputs of sample k (held between reports) */
} RemusState;

/* x' (15) for the state x, command [delta_r, delta_s (rad), n (rpm)], current (NED, m/s) */
void remus_derivative(const double *p, const double *x, const double *cmd, const double *cur,
                      double *out);
/* x <- `substeps` RK4 steps of dt (s), command and current held */
void remus_rk4(const double *p, double *x, const double *cmd, const double *cur, double dt,
               int substeps);
/* the start: s from x0 = [p; v_g] and w0 (plant.initial_state), the generators seeded
   [seed, vehicle] and [seed, 3000000 + vehicle], the first noise row and measurement */
void remus_reset(const RemusConst *c, RemusState *st, const double *x0, const double *w0,
                 uint32_t seed, uint32_t vehicle);
/* one communication step with the input held (force u (3, N) or the command [n (rpm),
   delta_r, delta_s (rad)]); 0 if the new state is finite, else -1 (st unchanged) */
int remus_step(const RemusConst *c, RemusState *st, const double *input);
/* the outputs of sample k: [y, x, w, attitude, rpm, rudder, stern, saturated] (19), then
   [velocity (3), rates (3), depth] if actuated, then nav (10) with sensors */
void remus_outputs(const RemusConst *c, const RemusState *st, double *o);

#endif
