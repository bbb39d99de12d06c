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
} ModelState;

#endif
