/*
 * c_host: a fixed-step FMI 2.0 co-simulation master for a whole system, in plain C99 (libc,
 * libdl, libm; no Python, no environment variables). It runs the native FMUs of
 * `auv-cosim export native` where no Python exists, and times them. It builds for Linux
 * (x86-64: binaries/linux64; aarch64: binaries/aarch64-linux) and for 64-bit Windows
 * (MinGW-w64: binaries/win64, LoadLibrary instead of dlopen; build it with
 * -D__USE_MINGW_ANSI_STDIO=1 so numbers are read and printed by MinGW's correctly rounded
 * routines, not msvcrt's).
 *
 *   c_host SYSTEM_FILE STEPS H OUT_CSV
 *
 * SYSTEM_FILE, one directive per line ('#' comments and blank lines ignored; the folder
 * is the last field, so it may hold spaces):
 *
 *   fmu <name> <model_identifier> <guid> <unzipped_folder>
 *   real <name> <vr> <value>           set in initialization mode (a parameter, a start)
 *   int <name> <vr> <value>
 *   connect <src> <src_vr> <dst> <dst_vr>     a Real output to a Real input
 *   record <name> <vr>                         a Real written to the CSV (in order)
 *   series <name> <vr> <file>    a Real input set before step k to line k of <file> (one
 *                                number a line, at least STEPS lines; the file is the last
 *                                field, so it may hold spaces)
 *
 * The library is <folder>/binaries/<platform>/<model_identifier>.so (.dll on Windows); the
 * resource location is the file URI of <folder>/resources, percent-encoded (RFC 3986;
 * on Windows file:///C:/..., a folder given as C:\... or C:/...).
 *
 * Algorithm (libcosim's fixed-step one, our master's "jacobi" coupling):
 *   read every connection source and record variable at t_0 -> row 0
 *   for k = 0 .. STEPS-1: set every destination from the values read last and every series
 *   input to its line k (all sets after all gets), fmi2DoStep(k H, H) on every FMU in file order, read again (t_(k+1)) -> row k+1
 * The CSV holds rows 0 .. STEPS-1: time, then the record variables, %.17g. One
 * fmi2GetReal and one fmi2SetReal per FMU and step. Printed on stdout: "us_per_step X",
 * the loop alone (CSV writing is after it).
 *
 * Exit status: 0 done; 1 an FMI call failed (one line naming the instance, the function,
 * t and the status, after the FMU's own message from the logger; everything instantiated
 * is freed); 2 a bad system file or a missing library.
 */
#ifdef _WIN32
#include <windows.h>
typedef HMODULE Lib;
#define PLATFORM "win64"
#define LIB_SUFFIX ".dll"
#else
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <time.h>
typedef void *Lib;
#ifdef __aarch64__
#define PLATFORM "aarch64-linux"
#else
#define PLATFORM "linux64"
#endif
#define LIB_SUFFIX ".so"
#endif
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

/* ------------------------------------------------------------------ the platform */
/* the library at path, or NULL with the reason in err */
static Lib lib_open(char *path, char *err, size_t n) {
#ifdef _WIN32
    for (char *p = path; *p; p++) if (*p == '/') *p = '\\';
    Lib lib = LoadLibraryA(path);
    if (!lib) snprintf(err, n, "cannot load %s (Windows error %lu)", path,
                       (unsigned long)GetLastError());
    return lib;
#else
    Lib lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) snprintf(err, n, "%s", dlerror());
    return lib;
#endif
}

static void *lib_sym(Lib lib, const char *name) {
#ifdef _WIN32
    return (void *)GetProcAddress(lib, name);
#else
    return dlsym(lib, name);
#endif
}

static void lib_close(Lib lib) {
#ifdef _WIN32
    FreeLibrary(lib);
#else
    dlclose(lib);
#endif
}

/* a monotonic clock, microseconds */
static double now_us(void) {
#ifdef _WIN32
    LARGE_INTEGER f, c;
    QueryPerformanceFrequency(&f);
    QueryPerformanceCounter(&c);
    return (double)c.QuadPart * 1e6 / (double)f.QuadPart;
#else
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e6 + (double)t.tv_nsec / 1e3;
#endif
}

typedef struct {
    char name[128], model[128], guid[128], dir[1024];
    Lib lib;
    fmi2Component c;
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup;
    fmi2EnterInitializationModeTYPE *enter_init;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2GetRealTYPE *get_real;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2DoStepTYPE *do_step;
    /* per step: one get of `nget` vrs into `got`, one set of `nset` vrs from `src` */
    fmi2ValueReference *get_vr, *set_vr;
    double *got, *put;
    size_t nget, nset;
} Fmu;

typedef struct { int fmu; fmi2ValueReference vr; double v; int is_int; } Start;
typedef struct { int src, dst; fmi2ValueReference svr, dvr; size_t slot, dslot; } Link;
typedef struct { int fmu; fmi2ValueReference vr; size_t slot; } Rec;
typedef struct { int fmu; fmi2ValueReference vr; size_t dslot, n; double *v; } Series;

static Fmu *fmus; static size_t nfmu;
static Start *starts; static size_t nstart;
static Link *links; static size_t nlink;
static Rec *recs; static size_t nrec;
static Series *series; static size_t nseries;

static void logger(fmi2ComponentEnvironment env, fmi2String inst, fmi2Status st,
                   fmi2String cat, fmi2String fmt, ...) {
    (void)env; (void)cat;
    if (st < fmi2Warning) return;
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "[%s] ", inst ? inst : "?");
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static const fmi2CallbackFunctions CALLBACKS = {logger, calloc, free, NULL, NULL};

static void *grow(void *p, size_t n, size_t size) {
    void *q = realloc(p, n * size);
    if (!q) { fprintf(stderr, "c_host: out of memory\n"); exit(2); }
    return q;
}

static int find(const char *name) {
    for (size_t i = 0; i < nfmu; i++) if (strcmp(fmus[i].name, name) == 0) return (int)i;
    return -1;
}

static void cleanup(void) {
    for (size_t i = 0; i < nfmu; i++) {
        Fmu *f = &fmus[i];
        if (f->c) { f->terminate(f->c); f->free_instance(f->c); }
        if (f->lib) lib_close(f->lib);
        free(f->get_vr); free(f->set_vr); free(f->got); free(f->put);
    }
    for (size_t i = 0; i < nseries; i++) free(series[i].v);
    free(fmus); free(starts); free(links); free(recs); free(series);
}

static void bad_file(int line, const char *msg) {
    fprintf(stderr, "c_host: system file line %d: %s\n", line, msg);
    cleanup();
    exit(2);
}

/* the file URI of dir/resources, every byte outside RFC 3986's unreserved set and '/'
   percent-encoded (on Windows: file:///C:/..., backslashes as slashes, the colon kept) */
static void resource_uri(const char *dir, char *out, size_t n) {
    static const char hex[] = "0123456789ABCDEF";
#ifdef _WIN32
    size_t k = (size_t)snprintf(out, n, "file:///");
    const char *keep = "-._~/:";
#else
    size_t k = (size_t)snprintf(out, n, "file://");
    const char *keep = "-._~/";
#endif
    char path[1100];
    snprintf(path, sizeof path, "%s/resources", dir);
    for (unsigned char *p = (unsigned char *)path; *p && k + 4 < n; p++) {
        if (*p == '\\') *p = '/';
        if ((*p >= 'A' && *p <= 'Z') || (*p >= 'a' && *p <= 'z') || (*p >= '0' && *p <= '9') ||
            strchr(keep, *p)) out[k++] = (char)*p;
        else { out[k++] = '%'; out[k++] = hex[*p >> 4]; out[k++] = hex[*p & 15]; }
    }
    out[k] = '\0';
}

#define SYM(f, field, name)                                                           \
    do {                                                                              \
        *(void **)(&(f)->field) = lib_sym((f)->lib, name);                            \
        if (!(f)->field) bad_file(line, "the FMU library lacks " name);               \
    } while (0)

static void read_system(const char *path) {
    FILE *fp = fopen(path, "r");
    if (!fp) { fprintf(stderr, "c_host: cannot open %s\n", path); exit(2); }
    char buf[2048];
    int line = 0;
    while (fgets(buf, sizeof buf, fp)) {
        line++;
        buf[strcspn(buf, "\r\n")] = '\0';
        char kw[16] = "", a[128] = "", b[128] = "", c[128] = "", d[128] = "";
        int off = 0;
        if (sscanf(buf, " %15s%n", kw, &off) < 1 || kw[0] == '#') continue;
        if (strcmp(kw, "fmu") == 0) {
            int used = 0;
            if (sscanf(buf + off, " %127s %127s %127s %n", a, b, c, &used) < 3 || !used)
                bad_file(line, "expected: fmu <name> <model_identifier> <guid> <folder>");
            fmus = grow(fmus, nfmu + 1, sizeof(Fmu));
            Fmu *f = &fmus[nfmu];
            memset(f, 0, sizeof *f);
            nfmu++;
            snprintf(f->name, sizeof f->name, "%s", a);
            snprintf(f->model, sizeof f->model, "%s", b);
            snprintf(f->guid, sizeof f->guid, "%s", c);
            snprintf(f->dir, sizeof f->dir, "%s", buf + off + used);
            char lib[1300], err[1500];
            snprintf(lib, sizeof lib, "%s/binaries/" PLATFORM "/%s" LIB_SUFFIX, f->dir, f->model);
            f->lib = lib_open(lib, err, sizeof err);
            if (!f->lib) bad_file(line, err);
            SYM(f, instantiate, "fmi2Instantiate"); SYM(f, free_instance, "fmi2FreeInstance");
            SYM(f, setup, "fmi2SetupExperiment");
            SYM(f, enter_init, "fmi2EnterInitializationMode");
            SYM(f, exit_init, "fmi2ExitInitializationMode"); SYM(f, terminate, "fmi2Terminate");
            SYM(f, get_real, "fmi2GetReal"); SYM(f, set_real, "fmi2SetReal");
            SYM(f, set_integer, "fmi2SetInteger"); SYM(f, do_step, "fmi2DoStep");
        } else if (strcmp(kw, "real") == 0 || strcmp(kw, "int") == 0) {
            unsigned vr;
            double v;
            if (sscanf(buf + off, " %127s %u %lf", a, &vr, &v) != 3)
                bad_file(line, "expected: real|int <name> <vr> <value>");
            int i = find(a);
            if (i < 0) bad_file(line, "no such fmu (declare it first)");
            starts = grow(starts, nstart + 1, sizeof(Start));
            starts[nstart++] = (Start){i, vr, v, kw[0] == 'i'};
        } else if (strcmp(kw, "connect") == 0) {
            unsigned sv, dv;
            if (sscanf(buf + off, " %127s %u %127s %u", a, &sv, d, &dv) != 4)
                bad_file(line, "expected: connect <src> <src_vr> <dst> <dst_vr>");
            int s = find(a), t = find(d);
            if (s < 0 || t < 0) bad_file(line, "no such fmu");
            links = grow(links, nlink + 1, sizeof(Link));
            links[nlink++] = (Link){s, t, sv, dv, 0, 0};
        } else if (strcmp(kw, "record") == 0) {
            unsigned vr;
            if (sscanf(buf + off, " %127s %u", a, &vr) != 2)
                bad_file(line, "expected: record <name> <vr>");
            int i = find(a);
            if (i < 0) bad_file(line, "no such fmu");
            recs = grow(recs, nrec + 1, sizeof(Rec));
            recs[nrec++] = (Rec){i, vr, 0};
        } else if (strcmp(kw, "series") == 0) {
            unsigned vr;
            int used = 0;
            if (sscanf(buf + off, " %127s %u %n", a, &vr, &used) < 2 || !used)
                bad_file(line, "expected: series <name> <vr> <file>");
            int i = find(a);
            if (i < 0) bad_file(line, "no such fmu");
            series = grow(series, nseries + 1, sizeof(Series));
            Series *s = &series[nseries++];
            *s = (Series){i, vr, 0, 0, NULL};
            FILE *sf = fopen(buf + off + used, "r");
            if (!sf) bad_file(line, "cannot open the series file");
            char num[128];
            while (fgets(num, sizeof num, sf)) {
                char *end;
                double v = strtod(num, &end);
                if (end == num) continue;           /* a blank line */
                s->v = grow(s->v, s->n + 1, sizeof(double));
                s->v[s->n++] = v;
            }
            fclose(sf);
        } else {
            bad_file(line, "unknown directive (fmu, real, int, connect, record, series)");
        }
    }
    fclose(fp);
}

/* the slot of vr in FMU i's get list (added if new) */
static size_t get_slot(int i, fmi2ValueReference vr) {
    Fmu *f = &fmus[i];
    for (size_t k = 0; k < f->nget; k++) if (f->get_vr[k] == vr) return k;
    f->get_vr = grow(f->get_vr, f->nget + 1, sizeof *f->get_vr);
    f->get_vr[f->nget] = vr;
    return f->nget++;
}

static void plan(void) {
    for (size_t l = 0; l < nlink; l++) {
        links[l].slot = get_slot(links[l].src, links[l].svr);
        Fmu *t = &fmus[links[l].dst];
        t->set_vr = grow(t->set_vr, t->nset + 1, sizeof *t->set_vr);
        t->set_vr[t->nset] = links[l].dvr;
        links[l].dslot = t->nset++;
    }
    for (size_t q = 0; q < nseries; q++) {
        Fmu *t = &fmus[series[q].fmu];
        t->set_vr = grow(t->set_vr, t->nset + 1, sizeof *t->set_vr);
        t->set_vr[t->nset] = series[q].vr;
        series[q].dslot = t->nset++;
    }
    for (size_t r = 0; r < nrec; r++) recs[r].slot = get_slot(recs[r].fmu, recs[r].vr);
    for (size_t i = 0; i < nfmu; i++) {
        fmus[i].got = calloc(fmus[i].nget ? fmus[i].nget : 1, sizeof(double));
        fmus[i].put = calloc(fmus[i].nset ? fmus[i].nset : 1, sizeof(double));
    }
}

static const char *status_name(int st) {
    static const char *names[] = {"OK", "Warning", "Discard", "Error", "Fatal", "Pending"};
    return st >= 0 && st < 6 ? names[st] : "unknown status";
}

/* the FMU's own message came just before, through the logger (its instance in brackets) */
static void fail_status(const Fmu *f, const char *fn, double t, int st) {
    fprintf(stderr, "c_host: %s %s failed at t = %.17g (%s)\n", f->name, fn, t,
            status_name(st));
    cleanup();
    exit(1);
}

/* a call whose status is worse than fmi2Warning ends the run, naming it and the status */
#define CHECK(f, call, fn, t) \
    do { int st_ = (call); if (st_ > fmi2Warning) fail_status((f), (fn), (t), st_); } while (0)

static void fail(const Fmu *f, const char *fn, double t) {
    fprintf(stderr, "c_host: %s %s failed at t = %.17g\n", f->name, fn, t);
    cleanup();
    exit(1);
}

static void read_all(double t) {
    for (size_t i = 0; i < nfmu; i++)
        if (fmus[i].nget)
            CHECK(&fmus[i], fmus[i].get_real(fmus[i].c, fmus[i].get_vr, fmus[i].nget,
                                             fmus[i].got), "fmi2GetReal", t);
}

int main(int argc, char **argv) {
    if (argc != 5) {
        fprintf(stderr, "usage: c_host SYSTEM_FILE STEPS H OUT_CSV\n");
        return 2;
    }
    long steps = strtol(argv[2], NULL, 10);
    double h = strtod(argv[3], NULL);
    if (steps < 1 || !(h > 0.0)) { fprintf(stderr, "c_host: STEPS >= 1 and H > 0\n"); return 2; }
    read_system(argv[1]);
    for (size_t q = 0; q < nseries; q++)
        if (series[q].n < (size_t)steps) {
            fprintf(stderr, "c_host: series %zu of %s has %zu values, fewer than %ld steps\n",
                    q + 1, fmus[series[q].fmu].name, series[q].n, steps);
            cleanup();
            return 2;
        }
    plan();
    for (size_t i = 0; i < nfmu; i++) {
        Fmu *f = &fmus[i];
        char uri[4096];
        resource_uri(f->dir, uri, sizeof uri);
        f->c = f->instantiate(f->name, fmi2CoSimulation, f->guid, uri, &CALLBACKS, fmi2False,
                              fmi2False);
        if (!f->c) fail(f, "fmi2Instantiate", 0.0);
        CHECK(f, f->setup(f->c, fmi2False, 0.0, 0.0, fmi2False, 0.0), "fmi2SetupExperiment",
              0.0);
        CHECK(f, f->enter_init(f->c), "fmi2EnterInitializationMode", 0.0);
    }
    for (size_t s = 0; s < nstart; s++) {
        Fmu *f = &fmus[starts[s].fmu];
        fmi2Status st;
        if (starts[s].is_int) {
            fmi2Integer v = (fmi2Integer)starts[s].v;
            st = f->set_integer(f->c, &starts[s].vr, 1, &v);
        } else {
            st = f->set_real(f->c, &starts[s].vr, 1, &starts[s].v);
        }
        CHECK(f, st, "setting a start value", 0.0);
    }
    for (size_t i = 0; i < nfmu; i++)
        CHECK(&fmus[i], fmus[i].exit_init(fmus[i].c), "fmi2ExitInitializationMode", 0.0);

    double *rows = calloc((size_t)steps * (nrec + 1), sizeof(double));
    if (!rows) { fprintf(stderr, "c_host: out of memory\n"); cleanup(); return 2; }
    double t0 = now_us();
    read_all(0.0);
    for (long k = 0; k < steps; k++) {
        double t = (double)k * h;
        double *row = rows + (size_t)k * (nrec + 1);
        row[0] = t;
        for (size_t r = 0; r < nrec; r++) row[r + 1] = fmus[recs[r].fmu].got[recs[r].slot];
        for (size_t l = 0; l < nlink; l++)
            fmus[links[l].dst].put[links[l].dslot] = fmus[links[l].src].got[links[l].slot];
        for (size_t q = 0; q < nseries; q++)
            fmus[series[q].fmu].put[series[q].dslot] = series[q].v[k];
        for (size_t i = 0; i < nfmu; i++)
            if (fmus[i].nset)
                CHECK(&fmus[i], fmus[i].set_real(fmus[i].c, fmus[i].set_vr, fmus[i].nset,
                                                 fmus[i].put), "fmi2SetReal", t);
        for (size_t i = 0; i < nfmu; i++)
            CHECK(&fmus[i], fmus[i].do_step(fmus[i].c, t, h, fmi2True), "fmi2DoStep", t);
        if (k + 1 < steps) read_all((double)(k + 1) * h);
    }
    double us = (now_us() - t0) / (double)steps;
    printf("us_per_step %.4f\n", us);

    FILE *out = fopen(argv[4], "w");
    if (!out) { fprintf(stderr, "c_host: cannot write %s\n", argv[4]); free(rows); cleanup(); return 2; }
    fprintf(out, "time");
    for (size_t r = 0; r < nrec; r++) fprintf(out, ",%s.%u", fmus[recs[r].fmu].name, recs[r].vr);
    fputc('\n', out);
    for (long k = 0; k < steps; k++) {
        const double *row = rows + (size_t)k * (nrec + 1);
        for (size_t j = 0; j <= nrec; j++) fprintf(out, j ? ",%.17g" : "%.17g", row[j]);
        fputc('\n', out);
    }
    fclose(out);
    free(rows);
    cleanup();
    return 0;
}
