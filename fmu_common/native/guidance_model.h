/*
 * The evolving state of the native AuvGuidance (guidance_fmu.c). Included by the generated
 * native_model.h, which also defines the value references VR_<name> of the variables.
 */
#ifndef GUIDANCE_MODEL_H
#define GUIDANCE_MODEL_H

typedef struct {
    double v[3];            /* the reference velocity v_ref through the water, NED, m/s */
    double depth;           /* the depth set-point z_d, m */
    double held;            /* the course held while |v_h| <= U_min, rad */
} ModelState;

#endif
