/*
 * The linear system's part of a native FMU's data (linear_fmu.c): its table types and its
 * evolving state. Included by the generated native_model.h after the sizes NQ, NXI, NSTREAMS.
 */
#ifndef LINEAR_MODEL_H
#define LINEAR_MODEL_H

#include <stdint.h>

#include "numpy_random.h"

typedef struct {
    const char *name;
    unsigned offset, rows, cols, row0, col0;
    double sign;
    int vector;
    unsigned row_base;      /* its rows' ends in ModelState.row_end[row_base .. + rows] */
} RoleInfo;
typedef struct {
    int keyed;              /* default_rng([seed, key]) if 1, default_rng(seed) if 0 */
    uint32_t key;
    unsigned count;         /* normals per step, xi[offset .. offset + count) */
} StreamInfo;

typedef struct {
    double q[ALLOC(NQ)];               /* the state */
    double xi[ALLOC(NXI)];             /* the noise draw of the current step */
    NprPcg64 rng[ALLOC(NSTREAMS)];     /* one numpy PCG64 per noise stream */
    /* the non-zero entries of the roles, found when the parameters are final
       (model_reset): row i of a role holds nz_val/nz_col[row_end[b + i] .. row_end[b + i + 1])
       with b its row_base */
    double nz_val[ALLOC(NPAR)];
    uint32_t nz_col[ALLOC(NPAR)];
    uint32_t row_end[ALLOC(NROW_ENDS)];
} ModelState;

#endif
