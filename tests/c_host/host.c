/*
 * A minimal FMI 2.0 co-simulation master in C for one extracted FMU (no FMI headers,
 * no Python of its own): what a non-Python tool does with our pythonfmu FMUs.
 *
 *   host FMU_DIR --in NAME,NAME,... --out NAME,NAME,... [--h STEP] [--exit MODE]
 *
 * FMU_DIR is an extracted FMU (modelDescription.xml, binaries/linux64/<id>.so,
 * resources/). The host reads the GUID, the model identifier and the value references
 * of the named variables from modelDescription.xml, dlopens the binary, instantiates
 * (logger callback printing every message to stderr), sets up the experiment, enters and
 * exits initialization mode, then for every line of stdin (one value per --in name):
 * fmi2SetReal(inputs), fmi2GetReal(outputs), prints "k out1 out2 ..." (%.17g) to stdout,
 * fmi2DoStep(k h, h). At EOF: fmi2Terminate, fmi2FreeInstance, and leaves by MODE:
 *
 *   return       return from main (exit handlers and library destructors run)
 *   exit         exit(0) (the same)
 *   _exit        fflush, then _exit(0): no exit handlers, no library destructors
 *   dlclose      dlclose the FMU library, then return from main
 *   pythonfmu    call the FMU library's finalizePythonInterpreter() (pythonfmu's own
 *                teardown, exported by its binary), then return from main
 *   finalize     only with --init-python: the host owns the interpreter (see below)
 *                and calls Py_FinalizeEx itself before returning
 *
 * --init-python: the host initializes Python itself (Py_InitializeEx(0) from the
 * libpython already in the process, LD_PRELOAD or --libpython) before loading the FMU,
 * and releases the GIL (PyEval_SaveThread). pythonfmu then finds Python initialized and
 * leaves finalization to the host.
 * --libpython PATH: dlopen PATH with RTLD_GLOBAL before the FMU (instead of LD_PRELOAD).
 * --no-free: skip fmi2Terminate / fmi2FreeInstance.
 * A line "# status" on stderr reports the FMI status of every call that is not fmi2OK.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <limits.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Boolean;
typedef const char *fmi2String;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;

typedef struct {
    void (*logger)(fmi2ComponentEnvironment, fmi2String, fmi2Status, fmi2String, fmi2String, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

typedef fmi2Component (*fInstantiate)(fmi2String, fmi2Type, fmi2String, fmi2String,
                                      const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
typedef fmi2Status (*fSetupExperiment)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real,
                                       fmi2Boolean, fmi2Real);
typedef fmi2Status (*fComponent)(fmi2Component);
typedef void (*fFreeInstance)(fmi2Component);
typedef fmi2Status (*fRealIO)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Real *);
typedef fmi2Status (*fDoStep)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);
typedef const char *(*fString)(void);

static const char *STATUS[] = {"OK", "Warning", "Discard", "Error", "Fatal", "Pending"};

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    (void)env;
    va_list ap;
    fprintf(stderr, "[%s] %s (%s): ", (unsigned)status < 6 ? STATUS[status] : "?",
            instance ? instance : "", category ? category : "");
    va_start(ap, message);
    vfprintf(stderr, message ? message : "", ap);
    va_end(ap);
    fputc('\n', stderr);
    fflush(stderr);
}

static void die(const char *what)
{
    fprintf(stderr, "host: %s\n", what);
    fflush(stderr);
    _exit(3);
}

static char *read_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    if (fread(buf, 1, (size_t)n, f) != (size_t)n) { fclose(f); free(buf); return NULL; }
    buf[n] = '\0';
    fclose(f);
    return buf;
}

/* value of attribute `attr` within [start, end) (copied to out) */
static int attribute(const char *start, const char *end, const char *attr, char *out, size_t cap)
{
    char key[128];
    snprintf(key, sizeof key, " %s=\"", attr);
    const char *p = start;
    while ((p = strstr(p, key)) && p < end) {
        p += strlen(key);
        const char *q = strchr(p, '"');
        if (!q || q > end || (size_t)(q - p) >= cap) return 0;
        memcpy(out, p, (size_t)(q - p));
        out[q - p] = '\0';
        return 1;
    }
    return 0;
}

/* value reference of the ScalarVariable called `name` */
static int value_reference(const char *xml, const char *name, fmi2ValueReference *vr)
{
    const char *p = xml;
    char found[512], text[64];
    while ((p = strstr(p, "<ScalarVariable"))) {
        const char *end = strchr(p, '>');
        if (!end) return 0;
        if (attribute(p, end, "name", found, sizeof found) && strcmp(found, name) == 0 &&
            attribute(p, end, "valueReference", text, sizeof text)) {
            *vr = (fmi2ValueReference)strtoul(text, NULL, 10);
            return 1;
        }
        p = end;
    }
    return 0;
}

static size_t split(char *list, char **items, size_t cap)
{
    size_t n = 0;
    for (char *tok = strtok(list, ","); tok && n < cap; tok = strtok(NULL, ",")) items[n++] = tok;
    return n;
}

static void *sym(void *lib, const char *name)
{
    void *f = dlsym(lib, name);
    if (!f) { fprintf(stderr, "host: %s missing: %s\n", name, dlerror()); _exit(3); }
    return f;
}

static void check(const char *call, fmi2Status st)
{
    if (st != fmi2OK) {
        fprintf(stderr, "# status %s: %s\n", call, (unsigned)st < 6 ? STATUS[st] : "?");
        if (st >= fmi2Error) die("an FMI call failed");
    }
}

int main(int argc, char **argv)
{
    if (argc < 2) die("usage: host FMU_DIR --in a,b --out c,d [--h STEP] [--exit MODE]");
    const char *dir = argv[1];
    char *in_list = NULL, *out_list = NULL, *libpython = NULL;
    const char *exit_mode = "return";
    double h = 0.01;
    int init_python = 0, no_free = 0;
    for (int i = 2; i < argc; i++) {
        if (!strcmp(argv[i], "--in") && i + 1 < argc) in_list = argv[++i];
        else if (!strcmp(argv[i], "--out") && i + 1 < argc) out_list = argv[++i];
        else if (!strcmp(argv[i], "--h") && i + 1 < argc) h = atof(argv[++i]);
        else if (!strcmp(argv[i], "--exit") && i + 1 < argc) exit_mode = argv[++i];
        else if (!strcmp(argv[i], "--libpython") && i + 1 < argc) libpython = argv[++i];
        else if (!strcmp(argv[i], "--init-python")) init_python = 1;
        else if (!strcmp(argv[i], "--no-free")) no_free = 1;
        else die("unknown argument");
    }
    if (!in_list || !out_list) die("--in and --out are required");

    char path[PATH_MAX], absdir[PATH_MAX];
    if (!realpath(dir, absdir)) die("FMU directory not found");
    snprintf(path, sizeof path, "%s/modelDescription.xml", absdir);
    char *xml = read_file(path);
    if (!xml) die("cannot read modelDescription.xml");
    char guid[128], model[256];
    const char *root = strstr(xml, "<fmiModelDescription");
    const char *cs = strstr(xml, "<CoSimulation");
    if (!root || !cs || !attribute(root, strchr(root, '>'), "guid", guid, sizeof guid) ||
        !attribute(cs, strchr(cs, '>'), "modelIdentifier", model, sizeof model))
        die("no guid or CoSimulation modelIdentifier in modelDescription.xml");

    char *in_names[256], *out_names[256];
    size_t nin = split(in_list, in_names, 256), nout = split(out_list, out_names, 256);
    fmi2ValueReference vin[256], vout[256];
    for (size_t i = 0; i < nin; i++)
        if (!value_reference(xml, in_names[i], &vin[i])) { fprintf(stderr, "host: no variable %s\n", in_names[i]); _exit(3); }
    for (size_t i = 0; i < nout; i++)
        if (!value_reference(xml, out_names[i], &vout[i])) { fprintf(stderr, "host: no variable %s\n", out_names[i]); _exit(3); }

    void *py = NULL;
    if (libpython && !(py = dlopen(libpython, RTLD_NOW | RTLD_GLOBAL))) die(dlerror());
    void *pystate = NULL;
    if (init_python) {
        /* the interpreter comes from the libpython already loaded (LD_PRELOAD or --libpython) */
        void (*init)(int) = (void (*)(int))dlsym(py ? py : RTLD_DEFAULT, "Py_InitializeEx");
        void *(*save)(void) = (void *(*)(void))dlsym(py ? py : RTLD_DEFAULT, "PyEval_SaveThread");
        if (!init || !save) die("--init-python needs libpython in the process");
        init(0);
        pystate = save();           /* release the GIL: pythonfmu takes it per call */
        fprintf(stderr, "# host initialized Python\n");
    }

    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", absdir, model);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) die(dlerror());
    fInstantiate instantiate = (fInstantiate)sym(lib, "fmi2Instantiate");
    fSetupExperiment setup = (fSetupExperiment)sym(lib, "fmi2SetupExperiment");
    fComponent enter = (fComponent)sym(lib, "fmi2EnterInitializationMode");
    fComponent exit_init = (fComponent)sym(lib, "fmi2ExitInitializationMode");
    fComponent terminate = (fComponent)sym(lib, "fmi2Terminate");
    fFreeInstance free_instance = (fFreeInstance)sym(lib, "fmi2FreeInstance");
    fRealIO set_real = (fRealIO)sym(lib, "fmi2SetReal");
    fRealIO get_real = (fRealIO)sym(lib, "fmi2GetReal");
    fDoStep do_step = (fDoStep)sym(lib, "fmi2DoStep");
    fString version = (fString)sym(lib, "fmi2GetVersion");
    fString platform = (fString)sym(lib, "fmi2GetTypesPlatform");
    fprintf(stderr, "# %s: FMI %s, types platform %s\n", model, version(), platform());

    char resources[PATH_MAX + 16];
    snprintf(resources, sizeof resources, "file://%s/resources", absdir);
    fmi2CallbackFunctions callbacks = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("c_host", fmi2CoSimulation, guid, resources, &callbacks, 0, 1);
    if (!c) die("fmi2Instantiate returned NULL");
    check("fmi2SetupExperiment", setup(c, 0, 0.0, 0.0, 0, 0.0));
    check("fmi2EnterInitializationMode", enter(c));
    check("fmi2ExitInitializationMode", exit_init(c));

    char line[65536];
    fmi2Real u[256], x[256];
    long k = 0;
    while (fgets(line, sizeof line, stdin)) {
        char *p = line, *e;
        size_t got = 0;
        for (; got < nin; got++) {
            x[got] = strtod(p, &e);
            if (e == p) break;
            p = e;
        }
        if (got == 0) continue;
        if (got != nin) die("an input line has too few values");
        check("fmi2SetReal", set_real(c, vin, nin, x));
        check("fmi2GetReal", get_real(c, vout, nout, u));
        printf("%ld", k);
        for (size_t i = 0; i < nout; i++) printf(" %.17g", u[i]);
        printf("\n");
        check("fmi2DoStep", do_step(c, (double)k * h, h, 1));
        k++;
    }
    fflush(stdout);
    if (!no_free) {
        check("fmi2Terminate", terminate(c));
        free_instance(c);
        fprintf(stderr, "# freed the instance after %ld steps\n", k);
    }
    fflush(NULL);

    if (!strcmp(exit_mode, "_exit")) {
        fprintf(stderr, "# leaving by _exit\n");
        fflush(NULL);
        _exit(0);
    } else if (!strcmp(exit_mode, "exit")) {
        fprintf(stderr, "# leaving by exit\n");
        exit(0);
    } else if (!strcmp(exit_mode, "dlclose")) {
        int rc = dlclose(lib);
        void *again = dlopen(path, RTLD_NOW | RTLD_NOLOAD);
        fprintf(stderr, "# dlclose returned %d, library still mapped: %s\n", rc, again ? "yes" : "no");
    } else if (!strcmp(exit_mode, "pythonfmu")) {
        /* pythonfmu 0.7 resets its static std::shared_ptr<PyState> here and again in a
         * library destructor after the C++ static destructor already ran (use after
         * free at exit); resetting it now, while the library is intact, leaves an empty
         * shared_ptr for both later resets and finalizes Python if pythonfmu started it */
        void (*fin)(void) = (void (*)(void))dlsym(lib, "finalizePythonInterpreter");
        if (!fin) die("the FMU library exports no finalizePythonInterpreter");
        fin();
        fprintf(stderr, "# called finalizePythonInterpreter\n");
    } else if (!strcmp(exit_mode, "finalize")) {
        if (!init_python) die("--exit finalize needs --init-python");
        void (*restore)(void *) = (void (*)(void *))dlsym(py ? py : RTLD_DEFAULT, "PyEval_RestoreThread");
        int (*fin)(void) = (int (*)(void))dlsym(py ? py : RTLD_DEFAULT, "Py_FinalizeEx");
        restore(pystate);
        int rc = fin();
        fprintf(stderr, "# host called Py_FinalizeEx: %d\n", rc);
    }
    fprintf(stderr, "# leaving by return from main\n");
    fflush(NULL);
    free(xml);
    return 0;
}
