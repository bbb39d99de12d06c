/*
 * The evolving part of the native AuvRemus6dof / AuvRemus6dofActuated (remus6dof_fmu.c):
 * the vehicle's numbers for this run (the export's, with the gains and sub-steps of the
 * parameters) and its state. Included by the generated native_model.h.
 */
#ifndef REMUS6DOF_FMU_H
#define REMUS6DOF_FMU_H

#include "remus6dof_model.h"

typedef struct {
    RemusConst c;
    RemusState st;
} ModelState;

#endif
