/*
 * The evolving state of the native AuvAutopilot (autopilot_fmu.c). Included by the
 * generated native_model.h, which also defines the value references VR_<name>.
 */
#ifndef AUTOPILOT_MODEL_H
#define AUTOPILOT_MODEL_H

typedef struct {
    double integrals[2];    /* [int (U_d - U) dt (m), int (gamma_d - gamma) dt (rad s)] */
} ModelState;

#endif
