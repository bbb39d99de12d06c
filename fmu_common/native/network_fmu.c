/*
 * AuvNetwork (one vehicle's acoustic inbox) as a native FMU on the shared FMI plumbing
 * (fmu_core.c), in plain C99: the same link timing, loss draws, receiver and interface as
 * the pythonfmu AuvNetwork (plant_model/acoustic/auv_network_slave.py, links.py, inbox.py);
 * the generated native_model.h is made from its modelDescription (the same variable names,
 * units and structure; Real and Integer value references counted per type).
 *
 * Per link, at the transition from step k to k + 1 (t = k h):
 *
 *   1. the send steps skipped are passed (m: the next message's number; its send step is
 *      round(offset / h) + round(m period / h), rounding half to even as Python does);
 *   2. if k is a send step the tx inputs leave; the message is lost as the link's loss
 *      model draws it (plant_model/acoustic/link_models.py): independent, a uniform draw
 *      of the link's stream below `loss` (numpy's Generator.random(): (next_uint64 >> 11)
 *      2^-53 of PCG64 seeded by SeedSequence([seed, 1000000 + key])); Gilbert-Elliott, a
 *      uniform u1 steps the channel state (s_0 = bad iff u1 < p_gb / (p_gb + p_bg); then
 *      good -> bad iff u1 < p_gb, bad stays iff u1 < 1 - p_bg), a second u2 < loss_good or
 *      loss_bad loses it; or (drawn all the same) if the link is down in the schedule's
 *      graph at k or out of the modem's range;
 *      it arrives at max(k + 1, ceil((k h + latency) / h - 1e-9));
 *   3. the messages due at k + 1 leave the queue: a lost one is counted, another becomes
 *      rx (with its send step) and is counted as delivered;
 *   4. unless M is the identity (hold), rx and every message in flight become M x.
 *
 * Outputs per link: rx, age = (k - k_sent(rx)) h, delivered, lost, in flight. Parameters
 * refused at initialization name the variable: a link timing plant_model.acoustic.links
 * refuses, a period or a switch time that is not whole steps of h, more messages in flight
 * than QCAP (the capacity this FMU was built for), a schedule that does not start at 0 or
 * increase, an `up` other than 0 or 1, a negative seed or key, h or range not positive.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#define NATIVE_MODEL_TABLES
#include "fmu_core.h"

#if !defined(NLINKS) || !defined(QCAP) || !defined(VR_h) || !defined(IVR_seed)
#error "native_model.h is not AuvNetwork's"
#endif

#define R(d, vr) ((d)->r[(vr)])
#define MAX_IN_FLIGHT 1000
#define LINK_KEY_BASE 1000000u

/* ------------------------------------------------------------------ names, start values */
void model_start_values(Data *d) {
    for (int i = 0; i < VR_OUT0; i++) d->r[i] = REAL_START[i];
    for (int i = 0; i < NINT; i++) d->ints[i] = INT_START[i];
}

void model_real_name(fmi2ValueReference vr, char *out, size_t n) {
    if (vr < NREAL) snprintf(out, n, "%s", REAL_NAMES[vr]);
    else snprintf(out, n, "value reference %u", vr);
}

const char *model_int_name(fmi2ValueReference vr) {
    return vr < (fmi2ValueReference)NINT ? INT_NAMES[vr] : "(no such Integer)";
}

/* ------------------------------------------------------------------ checks */
/* value (s) as whole steps h into *out, else -1 after logging (base.whole_steps) */
static int whole_steps(Instance *in, const char *name, double value, double h, int64_t *out) {
    double n = value / h, r = rint(n);
    if (value > 0.0 && r == 0.0) {
        fmu_log(in, fmi2Error, "%s = %g s is below one step h = %g s (messages leave on the "
                "co-simulation's steps, at most one per step)", name, value, h);
        return -1;
    }
    if (fabs(n - r) > 1e-9 * fmax(1.0, fabs(n)) || fabs(r) > 9.0e15) {
        fmu_log(in, fmi2Error, "%s = %g s is not a whole number of steps h = %g s (messages "
                "leave on the co-simulation's steps)", name, value, h);
        return -1;
    }
    *out = (int64_t)r;
    return 0;
}

/* link_models.GilbertElliott.parse: the four parameters of a bursty link */
static int check_bursts(Instance *in, const LinkInfo *L) {
    const Data *d = &in->d;
    double gb = R(d, L->p_gb), bg = R(d, L->p_bg), eg = R(d, L->loss_good);
    double eb = R(d, L->loss_bad);
    if (!(gb > 0.0 && gb <= 1.0)) {
        fmu_log(in, fmi2Error, "parameter %s.p_gb: %s: p_gb = %g is not a probability in "
                "(0, 1]", L->prefix, L->label, gb);
        return -1;
    }
    if (!(bg > 0.0 && bg <= 1.0)) {
        fmu_log(in, fmi2Error, "parameter %s.p_bg: %s: p_bg = %g is not a probability in "
                "(0, 1]", L->prefix, L->label, bg);
        return -1;
    }
    if (!(eg >= 0.0 && eg < 1.0)) {
        fmu_log(in, fmi2Error, "parameter %s.loss_good: %s: loss_good = %g is not a "
                "probability in [0, 1)", L->prefix, L->label, eg);
        return -1;
    }
    if (!(eb >= 0.0 && eb <= 1.0)) {
        fmu_log(in, fmi2Error, "parameter %s.loss_bad: %s: loss_bad = %g is not a "
                "probability in [0, 1]", L->prefix, L->label, eb);
        return -1;
    }
    if (eb < eg) {
        fmu_log(in, fmi2Error, "parameter %s.loss_bad: %s: loss_bad = %g is below loss_good "
                "= %g (the bad state loses at least as often as the good one)", L->prefix,
                L->label, eb, eg);
        return -1;
    }
    return 0;
}

/* a link's timing (links.check_link with h) and the capacity of its queue */
static int check_link(Instance *in, const LinkInfo *L) {
    const Data *d = &in->d;
    double lat = R(d, L->latency), per = R(d, L->period), p = R(d, L->loss);
    double off = R(d, L->offset), h = R(d, VR_h);
    char nm[160];
    int64_t steps;
    if (lat < 0.0) {
        fmu_log(in, fmi2Error, "parameter %s.latency: %s: latency = %g s is negative",
                L->prefix, L->label, lat);
        return -1;
    }
    if (!(per > 0.0)) {
        fmu_log(in, fmi2Error, "parameter %s.period: %s: period = %g s must be positive",
                L->prefix, L->label, per);
        return -1;
    }
    int model = L->model >= 0 ? d->ints[L->model] : 0;
    if (model != 0 && model != 1) {
        fmu_log(in, fmi2Error, "parameter %s.loss_model: %s: loss_model = %d is not one of "
                "0 (independent), 1 (gilbert-elliott)", L->prefix, L->label, model);
        return -1;
    }
    if (model == 0 && !(p >= 0.0 && p < 1.0)) {
        fmu_log(in, fmi2Error, "parameter %s.loss: %s: loss = %g is not a probability in "
                "[0, 1) (a link that loses every message carries nothing)", L->prefix,
                L->label, p);
        return -1;
    }
    if (model == 1 && check_bursts(in, L) != 0) return -1;
    if (!(off >= 0.0 && off < per)) {
        fmu_log(in, fmi2Error, "parameter %s.offset: %s: offset = %g s is not within "
                "[0, period = %g s)", L->prefix, L->label, off, per);
        return -1;
    }
    snprintf(nm, sizeof nm, "parameter %s.period: %s: period", L->prefix, L->label);
    if (whole_steps(in, nm, per, h, &steps) != 0) return -1;
    if (lat / per > MAX_IN_FLIGHT) {
        fmu_log(in, fmi2Error, "parameter %s.latency: %s: latency = %g s is %.3g periods of "
                "%g s: at most %d messages may be in flight on a link", L->prefix, L->label,
                lat, lat / per, per, MAX_IN_FLIGHT);
        return -1;
    }
    double need = ceil(lat / per) + 1.0;     /* LinkTiming.max_in_flight */
    if (need > QCAP) {
        fmu_log(in, fmi2Error, "parameter %s.latency: %s: latency = %g s at a period of %g s "
                "puts up to %.0f messages in flight; this native FMU was built for at most %d "
                "(export it again with these parameters)", L->prefix, L->label, lat, per,
                need, QCAP);
        return -1;
    }
    if (d->ints[L->key] < 0) {
        fmu_log(in, fmi2Error, "parameter %s.key = %d must not be negative", L->prefix,
                d->ints[L->key]);
        return -1;
    }
    return 0;
}

static int check_schedule(Instance *in) {
#if NGRAPHS > 0
    const Data *d = &in->d;
    double h = R(d, VR_h), T = R(d, VR_schedule_period);
    const double *t = d->r + VR_schedule_t;
    char nm[64];
    int64_t s;
    for (int g = 0; g < NGRAPHS; g++) {
        if ((g == 0 && t[0] != 0.0) || (g > 0 && !(t[g] > t[g - 1]))) {
            fmu_log(in, fmi2Error, "parameter schedule.t[%d] = %g s: the switch times must "
                    "start at 0 s and increase", g + 1, t[g]);
            return -1;
        }
        snprintf(nm, sizeof nm, "parameter schedule.t[%d]", g + 1);
        if (whole_steps(in, nm, t[g], h, &s) != 0) return -1;
    }
    if (!(T == 0.0 || T > t[NGRAPHS - 1])) {
        fmu_log(in, fmi2Error, "parameter schedule.period = %g s must be 0 or after the last "
                "switch at %g s", T, t[NGRAPHS - 1]);
        return -1;
    }
    if (T != 0.0 && whole_steps(in, "parameter schedule.period", T, h, &s) != 0) return -1;
    for (int j = 0; j < NLINKS; j++) {
        for (int g = 0; g < NGRAPHS; g++) {
            int u = d->ints[LINKS[j].up + g];
            if (u != 0 && u != 1) {
                fmu_log(in, fmi2Error, "parameter %s.up[%d] = %d must be 0 or 1",
                        LINKS[j].prefix, g + 1, u);
                return -1;
            }
        }
    }
#else
    (void)in;
#endif
    return 0;
}

int model_check(Instance *in) {
    const Data *d = &in->d;
    if (!(R(d, VR_h) > 0.0)) {
        fmu_log(in, fmi2Error, "parameter h = %g s must be a positive number", R(d, VR_h));
        return -1;
    }
    if (d->ints[IVR_seed] < 0) {
        fmu_log(in, fmi2Error, "parameter seed = %d must not be negative", d->ints[IVR_seed]);
        return -1;
    }
#if HAS_RANGE
    if (!(R(d, VR_range) > 0.0)) {
        fmu_log(in, fmi2Error, "parameter range = %g m must be positive", R(d, VR_range));
        return -1;
    }
#endif
    for (int j = 0; j < NLINKS; j++)
        if (check_link(in, &LINKS[j]) != 0) return -1;
    return check_schedule(in);
}

/* ------------------------------------------------------------------ state */
static int64_t steps_of(double v, double h) {
    double r = rint(v / h);
    return isfinite(r) && fabs(r) < 9.0e15 ? (int64_t)r : 0;
}

void model_reset(Data *d) {
    ModelState *s = &d->m;
    double h = R(d, VR_h) > 0.0 ? R(d, VR_h) : 1.0;
    memset(s, 0, sizeof *s);
    s->k = steps_of(d->t_next, h);
    for (int j = 0; j < NLINKS; j++) {
        const LinkInfo *L = &LINKS[j];
        LinkState *ls = &s->l[j];
        uint64_t entropy[2] = {(uint64_t)(uint32_t)d->ints[IVR_seed],
                               LINK_KEY_BASE + (uint64_t)(uint32_t)d->ints[L->key]};
        npr_seed(&ls->rng, entropy, 2);
        ls->first = steps_of(R(d, L->offset), h);
        ls->every = R(d, L->period) / h;
        ls->hold = 1;
        ls->channel = -1;
        for (int a = 0; a < L->w; a++) {
            ls->rx[a] = R(d, L->rx0 + a);
            for (int b = 0; b < L->w; b++)
                if (R(d, L->M + a * L->w + b) != (a == b ? 1.0 : 0.0)) ls->hold = 0;
        }
    }
#if NGRAPHS > 0
    for (int g = 0; g < NGRAPHS; g++) s->sw[g] = steps_of(R(d, VR_schedule_t + g), h);
    s->sched_period = R(d, VR_schedule_period) != 0.0 ? steps_of(R(d, VR_schedule_period), h)
                                                       : 0;
#endif
}

void model_outputs(Data *d) {
    const ModelState *s = &d->m;
    double h = R(d, VR_h);
    for (int j = 0; j < NLINKS; j++) {
        const LinkInfo *L = &LINKS[j];
        const LinkState *ls = &s->l[j];
        for (int a = 0; a < L->w; a++) d->r[L->rx + a] = ls->rx[a];
        d->r[L->age] = (double)(s->k - ls->rx_sent) * h;
        d->r[L->delivered] = (double)ls->delivered;
        d->r[L->lost] = (double)ls->lost;
        d->r[L->in_flight] = (double)ls->count;
    }
}

/* ------------------------------------------------------------------ stepping */
/* y = M x (w x w, row major), summed in order */
static void mul(const double *M, const double *x, double *y, int w) {
    for (int a = 0; a < w; a++) {
        double acc = 0.0;
        for (int b = 0; b < w; b++) acc += M[a * w + b] * x[b];
        y[a] = acc;
    }
}

/* the send step of message m: round(offset / h) + round(m period / h) */
static int64_t next_send(const LinkState *ls) {
    return ls->first + (int64_t)rint((double)ls->m * ls->every);
}

/* links.arrival_step */
static int64_t arrival_step(int64_t k, double h, double latency) {
    int64_t a = (int64_t)ceil(((double)k * h + latency) / h - 1e-9);
    return a > k + 1 ? a : k + 1;
}

/* the loss model's draw of one message (link_models: Independent.draw, GilbertElliott.draw) */
static int draw_loss(const Data *d, const LinkInfo *L, LinkState *ls) {
    if (L->model < 0 || d->ints[L->model] == 0)
        return npr_next_double(&ls->rng) < R(d, L->loss);
    double gb = R(d, L->p_gb), bg = R(d, L->p_bg);
    double u1 = npr_next_double(&ls->rng);
    if (ls->channel < 0) ls->channel = u1 < gb / (gb + bg);
    else if (ls->channel == 0) ls->channel = u1 < gb;
    else ls->channel = u1 < 1.0 - bg;
    return npr_next_double(&ls->rng) < R(d, ls->channel ? L->loss_bad : L->loss_good);
}

/* LinkChannel.advance: the transition of link j from step k to k + 1 */
static void advance(Data *d, int j, int64_t k, int heard) {
    const LinkInfo *L = &LINKS[j];
    LinkState *ls = &d->m.l[j];
    const int w = L->w;
    while (next_send(ls) < k) ls->m += 1;
    if (next_send(ls) == k) {
        ls->m += 1;
        ls->sent += 1;
        int lost = draw_loss(d, L, ls) || !heard;
        Msg *msg = &ls->q[(ls->head + ls->count) % QCAP];
        msg->arrival = arrival_step(k, R(d, VR_h), R(d, L->latency));
        msg->sent = k;
        msg->lost = lost;
        memcpy(msg->v, d->r + L->tx, (size_t)w * sizeof(double));
        ls->count += 1;                      /* model_check keeps it within QCAP */
    }
    while (ls->count > 0 && ls->q[ls->head].arrival <= k + 1) {
        const Msg *msg = &ls->q[ls->head];
        if (msg->lost) {
            ls->lost += 1;
        } else {
            memcpy(ls->rx, msg->v, (size_t)w * sizeof(double));
            ls->rx_sent = msg->sent;
            ls->delivered += 1;
        }
        ls->head = (ls->head + 1) % QCAP;
        ls->count -= 1;
    }
    if (!ls->hold) {
        const double *M = d->r + L->M;
        double tmp[WMAX];
        mul(M, ls->rx, tmp, w);
        memcpy(ls->rx, tmp, (size_t)w * sizeof(double));
        for (int n = 0; n < ls->count; n++) {
            Msg *msg = &ls->q[(ls->head + n) % QCAP];
            mul(M, msg->v, tmp, w);
            memcpy(msg->v, tmp, (size_t)w * sizeof(double));
        }
    }
}

#if HAS_RANGE
/* the sender's position (NED, m) of link j: H z for the leader, else its state's */
static void sender_position(const Data *d, const LinkInfo *L, double p[3]) {
    for (int a = 0; a < 3; a++) {
        if (L->leader) {
            double acc = 0.0;
            for (int b = 0; b < L->w; b++)
                acc += d->r[VR_leader_H + a * L->w + b] * d->r[L->tx + b];
            p[a] = acc;
        } else {
            p[a] = d->r[L->txx + POSITION_INDEX[a]];
        }
    }
}
#endif

/* is link j up at step k (modem range and schedule)? */
static int heard(const Data *d, int j, int64_t k) {
    int up = 1;
#if HAS_RANGE
    double p[3], acc = 0.0;
    sender_position(d, &LINKS[j], p);
    for (int a = 0; a < 3; a++) {
        double e = p[a] - d->r[VR_x + POSITION_INDEX[a]];
        acc += e * e;
    }
    up = sqrt(acc) <= R(d, VR_range);
#endif
#if NGRAPHS > 0
    const ModelState *s = &d->m;
    int64_t kk = s->sched_period ? k % s->sched_period : k;
    int g = 0;
    while (g + 1 < NGRAPHS && s->sw[g + 1] <= kk) g++;
    up = up && d->ints[LINKS[j].up + g];
#endif
    (void)d; (void)j; (void)k;
    return up;
}

int model_step(Instance *in, double t, double step) {
    (void)t; (void)step;
    Data *d = &in->d;
    int64_t k = d->m.k;
    int up[NLINKS > 0 ? NLINKS : 1];
    for (int j = 0; j < NLINKS; j++) up[j] = heard(d, j, k);   /* all before any advance */
    for (int j = 0; j < NLINKS; j++) advance(d, j, k, up[j]);
    d->m.k = k + 1;
    return 0;
}
