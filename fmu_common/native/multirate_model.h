/*
 * The evolving state of the native multi-rate navigation filter (multirate_fmu.c).
 * Included by the generated native_model.h after the size NS (the filter's state [x; w]).
 */
#ifndef MULTIRATE_MODEL_H
#define MULTIRATE_MODEL_H

typedef struct {
    double q[NS];           /* the prior estimate of [x; w] at this step */
    double P[NS * NS];      /* its covariance, row major */
} ModelState;

#endif
