/*
 * The evolving state of the native multi-rate navigation filter (multirate_fmu.c).
 * Included by the generated native_model.h after the size NS (the filter's state [x; w]).
 */
#ifndef MULTIRATE_MODEL_H
#define MULTIRATE_MODEL_H

typedef struct {
    double q[NS];           /* the prior estimate of [x; w] at this step */
    double P[NS * NS];      /* its covariance, row major */
    /* what model_outputs computed from q, P and the inputs (fmu_core.c computes the
       outputs before every step whose inputs changed): the estimate and the filtered
       covariance the step goes on from; ok = 0 if the innovation covariance was singular */
    double est[NS];
    double Pp[NS * NS];
    int ok;
} ModelState;

#endif
