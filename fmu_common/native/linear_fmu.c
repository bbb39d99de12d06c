/*
 * A discrete-time linear system on the shared FMI plumbing (fmu_core.c), in plain C99
 * (libc and libm only). Every designed FMU of auv-cosim (controller, estimator, linear
 * plant) is such a system once its Riccati and Sylvester equations are solved; the numbers
 * come from the generated header "native_model.h" (sizes, value references, start values,
 * names).
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
 * A system with a state (NQ > 0) takes only the step h and starts at t = 0; a static one
 * any step. The model refuses h <= 0, a negative seed or stream, and a step whose state
 * would turn non-finite (naming the state element and the time).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#define NATIVE_MODEL_TABLES
#include "fmu_core.h"

#define PAR(d) ((d)->r)
#define H(d) ((d)->r[NPAR])
#define U(d) ((d)->r + VR_IN0)
#define Y(d) ((d)->r + VR_OUT0)

/* ------------------------------------------------------------------ names, start values */
void model_start_values(Data *d) {
    for (int i = 0; i < NPAR; i++) d->r[i] = PAR_START[i];
    H(d) = H_START;
    if (NINT > 0) d->ints[0] = SEED_START;
    if (NINT > 1) d->ints[NINT - 1] = STREAM_START;
}

/* "K[2,3]" for a parameter entry, "h", "u[2]"-style names for the rest */
void model_real_name(fmi2ValueReference vr, char *out, size_t n) {
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
    if (vr >= VR_IN0 && vr < VR_OUT0) snprintf(out, n, "%s", INPUT_NAMES[vr - VR_IN0]);
    else if (vr >= VR_OUT0 && vr < NREAL) snprintf(out, n, "%s", OUTPUT_NAMES[vr - VR_OUT0]);
    else if (vr == NPAR) snprintf(out, n, "h");
    else snprintf(out, n, "value reference %u", vr);
}

const char *model_int_name(fmi2ValueReference vr) { return vr == 0 ? "seed" : "stream"; }

/* ------------------------------------------------------------------ noise */
static void seed_rng(Data *d) {
    for (int i = 0; i < NSTREAMS; i++) {
        uint64_t entropy[2] = {(uint64_t)(uint32_t)d->ints[0],
                               HAS_STREAM_PARAM && i == 0 ? (uint64_t)(uint32_t)d->ints[1]
                                                          : (uint64_t)STREAMS[i].key};
        npr_seed(&d->m.rng[i], entropy, STREAMS[i].keyed ? 2 : 1);
    }
}

/* xi of the step: stream by stream, as many normals as numpy's standard_normal((n, count))
   takes per row */
static void draw(Data *d) {
    int j = 0;
    for (int i = 0; i < NSTREAMS; i++)
        for (unsigned c = 0; c < STREAMS[i].count; c++)
            d->m.xi[j++] = npr_standard_normal(&d->m.rng[i]);
}

/* ------------------------------------------------------------------ the equations */
/* Index the non-zero entries of every matrix role, row by row (the parameters are final:
   fmi2ExitInitializationMode, fmi2Reset). The designed matrices of a fleet are mostly zero
   (a distributed controller's D: 15 of 2825 entries). */
static void index_nonzeros(Data *d) {
    for (int r = 0; r < NROLES; r++) {
        const RoleInfo *ri = &ROLES[r];
        const double *M = PAR(d) + ri->offset;
        uint32_t *row_end = d->m.row_end + ri->row_base;
        uint32_t k = ri->offset;
        row_end[0] = k;
        for (unsigned i = 0; i < ri->rows; i++) {
            for (unsigned j = 0; j < ri->cols; j++) {
                double m = M[(size_t)i * ri->cols + j];
                if (m != 0.0) {
                    d->m.nz_val[k] = m;
                    d->m.nz_col[k] = j;
                    k++;
                }
            }
            row_end[i + 1] = k;
        }
    }
}

/* out += M v[col0 ...] for the role r (rows x cols, row major in the parameters), over its
   non-zero entries in row order: for finite v the same sums bit for bit as over every entry
   (adding a zero product changes no non-zero sum; every row still adds its sum, so a zero
   keeps its sign as before) */
static void gemv_add(const Data *d, int r, const double *v, double *out) {
    if (r < 0) return;
    const RoleInfo *ri = &ROLES[r];
    const uint32_t *row_end = d->m.row_end + ri->row_base;
    const double *val = d->m.nz_val;
    const uint32_t *col = d->m.nz_col;
    v += ri->col0;
    out += ri->row0;
    for (unsigned i = 0; i < ri->rows; i++) {
        double acc = 0.0;
        for (uint32_t k = row_end[i]; k < row_end[i + 1]; k++) acc += val[k] * v[col[k]];
        out[i] += ri->sign * acc;
    }
}

static void add_vector(const Data *d, int r, double *out) {
    if (r < 0) return;
    const RoleInfo *ri = &ROLES[r];
    for (unsigned i = 0; i < ri->rows; i++) out[i] += ri->sign * PAR(d)[ri->offset + i];
}

/* y[row0 + i] clipped to [-s_i, s_i] for the role r (a vector of limits) */
static void clip(const Data *d, int r, double *y) {
    if (r < 0) return;
    const RoleInfo *ri = &ROLES[r];
    y += ri->row0;
    for (unsigned i = 0; i < ri->rows; i++) {
        double lim = PAR(d)[ri->offset + i];
        y[i] = y[i] < -lim ? -lim : y[i];                /* numpy.maximum(y, -lim) */
        y[i] = y[i] > lim ? lim : y[i];                  /* numpy.minimum(., lim) */
    }
}

/* y = C q + D u + c + G xi, then clipped by the role sat (a controller's force limit) */
void model_outputs(Data *d) {
    double *y = Y(d);
    for (int i = 0; i < NY; i++) y[i] = 0.0;
    gemv_add(d, ROLE_C, d->m.q, y);
    gemv_add(d, ROLE_D, U(d), y);
    add_vector(d, ROLE_c, y);
    gemv_add(d, ROLE_G, d->m.xi, y);
    clip(d, ROLE_sat, y);
}

/* q = q0, the generators seeded, the first draw */
void model_reset(Data *d) {
    index_nonzeros(d);
    for (int i = 0; i < NQ; i++) d->m.q[i] = ROLE_q0 >= 0 ? PAR(d)[ROLES[ROLE_q0].offset + i] : 0.0;
    seed_rng(d);
    draw(d);
}

int model_check(Instance *in) {
    Data *d = &in->d;
    if (!(H(d) > 0.0)) {
        fmu_log(in, fmi2Error, "parameter h = %g s must be a positive number", H(d));
        return -1;
    }
    for (int i = 0; i < NINT; i++) {
        if (d->ints[i] < 0) {
            fmu_log(in, fmi2Error, "parameter %s = %d must not be negative",
                    model_int_name((fmi2ValueReference)i), d->ints[i]);
            return -1;
        }
    }
    if (ROLE_sat >= 0) {
        for (unsigned i = 0; i < ROLES[ROLE_sat].rows; i++) {
            unsigned vr = ROLES[ROLE_sat].offset + i;
            if (!(PAR(d)[vr] > 0.0)) {
                char nm[64];
                model_real_name((fmi2ValueReference)vr, nm, sizeof nm);
                fmu_log(in, fmi2Error, "parameter %s = %g must be a positive force in N (the "
                        "actuator limit)", nm, PAR(d)[vr]);
                return -1;
            }
        }
    }
    return 0;
}

/* q(k+1) = A q + B u + Bo y + b + F xi, then the next draw */
int model_step(Instance *in, double t, double step) {
    Data *d = &in->d;
    double next[ALLOC(NQ)];
    for (int i = 0; i < NQ; i++) next[i] = 0.0;
    gemv_add(d, ROLE_A, d->m.q, next);
    gemv_add(d, ROLE_B, U(d), next);
    gemv_add(d, ROLE_Bo, Y(d), next);
    add_vector(d, ROLE_b, next);
    gemv_add(d, ROLE_F, d->m.xi, next);
    for (int i = 0; i < NQ; i++) {
        if (!isfinite(next[i])) {
            fmu_log(in, fmi2Error, "%s: state element %d would become %g in the step from "
                    "t = %g s to %g s (the step is not taken)", in->name, i + 1, next[i], t,
                    t + step);
            return -1;
        }
    }
    memcpy(d->m.q, next, sizeof(double) * NQ);
    draw(d);
    return 0;
}
