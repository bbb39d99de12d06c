/*
 * The FMI 2.0 co-simulation plumbing shared by the project's native (C99) FMUs
 * (fmu_core.c), and the hooks a model supplies (linear_fmu.c, guidance_fmu.c,
 * autopilot_fmu.c).
 *
 * Variables. Real value references: 0 .. NPARR-1 the Real parameters, then the NIN inputs
 * (VR_IN0 ..), then the NOUT outputs (VR_OUT0 ..); Integer value references 0 .. NINT-1
 * the Integer parameters; String value references 0 .. NSTRING-1 the String parameters
 * fixed at export (not in Data). The others live in one block (Data), with the model's evolving
 * state (ModelState, defined by the model's header) and the phase, step count and next
 * communication point: the FMU state is a copy of that block.
 *
 * The generated header "native_model.h" (orchestrator/cosim/native.py) defines NATIVE_GUID,
 * NREAL, NPARR, NIN, NOUT, NINT, STEP_VR (the value reference of the fixed step parameter h,
 * or -1 for an FMU that takes any step), START_AT_ZERO (1: fmi2SetupExperiment must start at
 * t = 0), includes the model's header (ModelState) and, where NATIVE_MODEL_TABLES is
 * defined (the model's own .c file), the model's tables (names, start values).
 *
 * The generated header "fmu_tolerances.h" (orchestrator/cosim/native_build.py) holds the
 * time tolerances the pythonfmu slaves use too (fmu_common/lifecycle.py): STEP_SIZE_TOLERANCE
 * (a fraction of h), COMM_POINT_TOLERANCE (a fraction of the step), TIME_ROUNDING (a
 * fraction of |t|).
 *
 * Errors never crash the host; each gives a status and a logged message naming the
 * variable or the time (fmu_core.c).
 */
#ifndef FMU_CORE_H
#define FMU_CORE_H

#include <stddef.h>
#include <stdint.h>

#include "fmi2Functions.h"
#include "fmu_tolerances.h"   /* generated (native_build.py) from fmu_common/lifecycle.py */

#define ALLOC(n) ((n) > 0 ? (n) : 1)

typedef enum { INSTANTIATED, INIT, STEPPING, TERMINATED } Phase;

#include "native_model.h"

/* String parameters (value references 0 .. NSTRING-1), fixed at export: none unless the
   generated header says otherwise */
#ifndef NSTRING
#define NSTRING 0
#endif

#define VR_IN0 NPARR
#define VR_OUT0 (NPARR + NIN)

/* everything that evolves or is set: one block, copied whole as the FMU state */
typedef struct {
    uint32_t magic, size;
    double r[ALLOC(NREAL)];      /* the Real variables by value reference */
    int ints[ALLOC(NINT)];       /* the Integer parameters by value reference */
    ModelState m;                /* the model's evolving state */
    int64_t k;                   /* steps taken */
    double t_next;               /* the communication point expected next, s */
    int dirty;                   /* the outputs must be recomputed */
    Phase phase;
} Data;

typedef struct {
    Data d;
    fmi2CallbackFunctions cb;
    char name[128];
    int logging;
} Instance;

/* a message to the host's logger (status st; category logStatusError unless fmi2OK) */
void fmu_log(Instance *in, fmi2Status st, const char *fmt, ...);

/* ------------------------------------------------------------------ the model's hooks */
/* the start values of the parameters (Real and Integer) and inputs into d->r, d->ints */
void model_start_values(Data *d);
/* the FMI name of the Real variable vr ("M[2]", "u[1]", "speed") */
void model_real_name(fmi2ValueReference vr, char *out, size_t n);
/* the FMI name of the Integer parameter vr */
const char *model_int_name(fmi2ValueReference vr);
/* with NSTRING > 0: the name and the exported value of the String parameter vr */
const char *model_string_name(fmi2ValueReference vr);
const char *model_string_value(fmi2ValueReference vr);
/* the parameters (already checked finite) at fmi2ExitInitializationMode: 0 if usable,
   else -1 after logging which one is not and why */
int model_check(Instance *in);
/* the evolving state from the parameters (instantiation, initialization, reset) */
void model_reset(Data *d);
/* the outputs d->r[VR_OUT0 ..] from the state, the parameters and the inputs */
void model_outputs(Data *d);
/* one step of size `step` (s) from t (s), the outputs of t just computed: 0 if taken,
   else -1 (logged; the state is left as it was) */
int model_step(Instance *in, double t, double step);

#endif
