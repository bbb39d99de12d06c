/*
 * The table-driven hooks of a native model whose variables are all Reals, listed in the
 * generated native_model.h (REAL_START: the start values up to the outputs, REAL_NAMES:
 * every FMI name) and that has no Integer variable: AuvGuidance and AuvAutopilot.
 * Included once, after fmu_core.h with NATIVE_MODEL_TABLES defined.
 */
#ifndef NAMED_REALS_H
#define NAMED_REALS_H

#include <stdio.h>

void model_start_values(Data *d) {
    for (int i = 0; i < VR_OUT0; i++) d->r[i] = REAL_START[i];
}

void model_real_name(fmi2ValueReference vr, char *out, size_t n) {
    if (vr < NREAL) snprintf(out, n, "%s", REAL_NAMES[vr]);
    else snprintf(out, n, "value reference %u", vr);
}

const char *model_int_name(fmi2ValueReference vr) { (void)vr; return "(no Integer)"; }

#endif
