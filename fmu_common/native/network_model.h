/*
 * The acoustic inbox's part of a native AuvNetwork FMU's data (network_fmu.c): the link
 * table's type and the evolving state. Included by the generated native_model.h after the
 * sizes NLINKS (links), WMAX (the widest message), QCAP (messages one link may have in
 * flight) and NGRAPHS (graphs of the switching schedule, 0 without one).
 */
#ifndef NETWORK_MODEL_H
#define NETWORK_MODEL_H

#include <stdint.h>

#include "numpy_random.h"

/* one link's variables: Real value references (-1: none), Integer ones for key and up */
typedef struct {
    const char *label;      /* names the link in messages, e.g. "link[2] of vehicle 3" */
    const char *prefix;     /* its FMI name prefix, "link[2]" or "leader" */
    int w;                  /* message size */
    int leader;             /* 1: the leader link (position H z with a modem range) */
    int latency, period, loss, offset, M, rx0, tx, rx, age, delivered, lost, in_flight, txx;
    int key, up;            /* Integer value references (up: -1 without a schedule) */
    int model;              /* Integer: its loss_model row (-1: independent, no variable) */
    int p_gb, p_bg, loss_good, loss_bad;   /* Gilbert-Elliott parameters (-1: none) */
} LinkInfo;

/* a message in flight: arrival and send step, lost or not, its value (propagated) */
typedef struct {
    int64_t arrival, sent;
    int lost;
    double v[WMAX];
} Msg;

/* one link (plant_model.acoustic.links.LinkChannel) */
typedef struct {
    NprPcg64 rng;           /* numpy default_rng([seed, 1000000 + key]) */
    int64_t first;          /* round(offset / h): the first send step */
    double every;           /* period / h */
    int64_t m;              /* the next message's number */
    int64_t rx_sent, sent, lost, delivered;
    int hold;               /* M is the identity: rx is held, not multiplied */
    int channel;            /* Gilbert-Elliott state: -1 not drawn yet, 0 good, 1 bad */
    int head, count;        /* the queue of messages in flight: a ring of QCAP */
    double rx[WMAX];        /* what the receiver holds now */
    Msg q[QCAP];
} LinkState;

typedef struct {
    int64_t k;                          /* the inbox's step (t = k h), next to advance */
    int64_t sw[NGRAPHS > 0 ? NGRAPHS : 1];  /* the schedule's switch steps */
    int64_t sched_period;               /* its period in steps (0: none) */
    LinkState l[NLINKS > 0 ? NLINKS : 1];
} ModelState;

#endif
