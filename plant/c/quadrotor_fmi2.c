/* FMI 2.0 co-simulation wrapper around quadrotor_physics: bookkeeping, checks and nothing else.
 *
 * Answers to bad input (tested in tests/plant/test_bad_input.py, documented in the README):
 *  - a non-finite value for any Real, an unknown value reference, setting an output, or setting a
 *    parameter after initialisation: fmi2Error, nothing in the call is applied (the call is checked
 *    whole before any value is stored), the instance stays usable;
 *  - a pulse width outside [esc_min_us, esc_max_us]: stored as given, clamped by the ESC model;
 *    a negative motor_health acts as 0;
 *  - parameters that make no physical sense: fmi2ExitInitializationMode returns fmi2Error and says
 *    which one; the instance stays in initialisation mode so they can be corrected;
 *  - a doStep with a non-positive or non-finite step, a communication point other than the
 *    instance's time, or one whose result would not be finite: fmi2Error, the state is unchanged.
 */
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "quadrotor_physics.h"

typedef enum { MODE_INSTANTIATED, MODE_INIT, MODE_STEP, MODE_TERMINATED } run_mode;
typedef enum { KIND_INPUT, KIND_PARAM, KIND_OUTPUT } var_kind;

/* Everything an FMU state holds: plain data, so it is copied and serialised as one block. */
typedef struct {
    int mode;
    double time;
    qr_inputs in;
    qr_params par;
    qr_state st;
    qr_outputs out;
    int outputs_valid;
} snapshot;

typedef struct {
    snapshot s;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    char name[128];
} instance;

static const char SNAPSHOT_MAGIC[8] = { 'Q', 'R', 'S', 'T', 'A', 'T', 'E', '1' };

static const char *MODE_NAMES[] = { "instantiated", "initialisation", "step", "terminated" };

static fmi2Status report(instance *m, fmi2Status status, const char *fmt, ...)
{
    if (m->logger == NULL)
        return status;
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    for (char *c = msg; *c; c++)
        if (*c == '%')
            *c = '#'; /* loggers treat the message as a printf format */
    m->logger(m->env, m->name, status, status == fmi2Error ? "logStatusError" : "logStatusWarning", msg);
    return status;
}

#define FIELD_INPUT(m, f) ((m)->s.in.f)
#define FIELD_PARAM(m, f) ((m)->s.par.f)
#define FIELD_OUTPUT(m, f) ((m)->s.out.f)

static void set_defaults(instance *m)
{
    memset(&m->s, 0, sizeof m->s);
#define X(vr, field, KIND, start, nm) FIELD_##KIND(m, field) = start;
    QR_REAL_VARIABLES(X)
    QR_INTEGER_VARIABLES(X)
    QR_BOOLEAN_VARIABLES(X)
#undef X
    m->s.mode = MODE_INSTANTIATED;
}

/* Each Real variable's place in the instance, by value reference (plant/variables.py numbers them
 * from 0 without gaps). fmi2GetReal reads every output after each step: through a switch on it that
 * cost the plant about a tenth of its instructions per FC cycle (bench/cycle_cost.py --breakdown). */
#define MEMBER_INPUT in
#define MEMBER_PARAM par
#define MEMBER_OUTPUT out
#define X(vr, field, KIND, start, nm) [vr] = offsetof(instance, s.MEMBER_##KIND.field),
static const size_t REAL_OFFSET[] = { QR_REAL_VARIABLES(X) };
#undef X
#define X(vr, field, KIND, start, nm) +1
enum { N_REAL = 0 QR_REAL_VARIABLES(X) };
#undef X
_Static_assert(sizeof REAL_OFFSET / sizeof REAL_OFFSET[0] == N_REAL, "Real value references are 0..N-1");
/* ... and its kind and name, for fmi2SetReal's checks: the inputs are written before every batch of
 * steps, where a switch per input and per pass cost about 2 k instructions per FC cycle */
#define X(vr, field, KIND, start, nm) [vr] = KIND_##KIND,
static const var_kind REAL_KIND[] = { QR_REAL_VARIABLES(X) };
#undef X
#define X(vr, field, KIND, start, nm) [vr] = nm,
static const char *const REAL_NAME[] = { QR_REAL_VARIABLES(X) };
#undef X

static double *real_at(instance *m, fmi2ValueReference vr) { return (double *)((char *)m + REAL_OFFSET[vr]); }

/* Integers and Booleans are both C ints here. */
static int *int_ref(instance *m, fmi2ValueReference vr, int boolean, var_kind *kind, const char **name)
{
    if (boolean) {
        switch (vr) {
#define X(vr, field, KIND, start, nm) \
    case vr:                          \
        *kind = KIND_##KIND;          \
        *name = nm;                   \
        return &FIELD_##KIND(m, field);
            QR_BOOLEAN_VARIABLES(X)
#undef X
        default:
            return NULL;
        }
    }
    switch (vr) {
#define X(vr, field, KIND, start, nm) \
    case vr:                          \
        *kind = KIND_##KIND;          \
        *name = nm;                   \
        return &FIELD_##KIND(m, field);
        QR_INTEGER_VARIABLES(X)
#undef X
    default:
        return NULL;
    }
}

/* Outputs are computed lazily: before initialisation ends they describe the initial state that the
 * current parameters and inputs give. */
static void refresh_outputs(instance *m)
{
    if (m->s.outputs_valid)
        return;
    if (m->s.mode == MODE_INSTANTIATED || m->s.mode == MODE_INIT) {
        if (qr_check_params(&m->s.par) != NULL)
            return; /* keep the last outputs */
        qr_init_state(&m->s.par, &m->s.in, &m->s.st);
    }
    qr_outputs_from(&m->s.par, &m->s.in, &m->s.st, &m->s.out);
    m->s.outputs_valid = 1;
}

static fmi2Status check_settable(instance *m, var_kind kind, const char *name)
{
    if (m->s.mode == MODE_TERMINATED)
        return report(m, fmi2Error, "cannot set %s: the instance is terminated", name);
    if (kind == KIND_OUTPUT)
        return report(m, fmi2Error, "cannot set %s: it is an output", name);
    if (kind == KIND_PARAM && m->s.mode == MODE_STEP)
        return report(m, fmi2Error,
                      "cannot set parameter %s after initialisation: parameters are fixed "
                      "(value not applied)",
                      name);
    return fmi2OK;
}

/* ---- FMI functions -------------------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    (void)c;
    (void)loggingOn;
    (void)nCategories;
    (void)categories;
    return fmi2OK; /* warnings and errors are always reported; there is no debug output */
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)fmuResourceLocation;
    (void)visible;
    (void)loggingOn;
    instance tmp = { 0 };
    if (functions != NULL) {
        tmp.logger = functions->logger;
        tmp.env = functions->componentEnvironment;
    }
    snprintf(tmp.name, sizeof tmp.name, "%s", instanceName ? instanceName : "quadrotor");
    if (fmuType != fmi2CoSimulation) {
        report(&tmp, fmi2Error, "only co-simulation is supported");
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, QR_GUID) != 0) {
        report(&tmp, fmi2Error, "GUID %s does not match this binary's %s", fmuGUID ? fmuGUID : "(null)", QR_GUID);
        return NULL;
    }
    instance *m = calloc(1, sizeof *m);
    if (m == NULL) {
        report(&tmp, fmi2Error, "out of memory");
        return NULL;
    }
    *m = tmp;
    set_defaults(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    instance *m = c;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (m->s.mode != MODE_INSTANTIATED)
        return report(m, fmi2Error, "fmi2SetupExperiment is only allowed before initialisation");
    if (!isfinite(startTime))
        return report(m, fmi2Error, "startTime must be finite");
    m->s.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    instance *m = c;
    if (m->s.mode != MODE_INSTANTIATED)
        return report(m, fmi2Error, "cannot enter initialisation from %s mode", MODE_NAMES[m->s.mode]);
    m->s.mode = MODE_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    instance *m = c;
    if (m->s.mode != MODE_INIT)
        return report(m, fmi2Error, "cannot exit initialisation from %s mode", MODE_NAMES[m->s.mode]);
    const char *why = qr_check_params(&m->s.par);
    if (why != NULL)
        return report(m, fmi2Error, "invalid parameters: %s", why);
    qr_init_state(&m->s.par, &m->s.in, &m->s.st);
    m->s.mode = MODE_STEP;
    m->s.outputs_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    ((instance *)c)->s.mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    set_defaults(c);
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    instance *m = c;
    refresh_outputs(m);
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= N_REAL)
            return report(m, fmi2Error, "no Real variable has value reference %u", vr[i]);
        value[i] = *real_at(m, vr[i]);
    }
    return fmi2OK;
}

static fmi2Status get_int(instance *m, const fmi2ValueReference vr[], size_t nvr, int value[], int boolean)
{
    var_kind kind;
    const char *name;
    refresh_outputs(m);
    for (size_t i = 0; i < nvr; i++) {
        int *p = int_ref(m, vr[i], boolean, &kind, &name);
        if (p == NULL)
            return report(m, fmi2Error, "no %s variable has value reference %u", boolean ? "Boolean" : "Integer",
                          vr[i]);
        value[i] = *p;
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    return get_int(c, vr, nvr, value, 0);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    return get_int(c, vr, nvr, value, 1);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    (void)vr;
    (void)value;
    return nvr == 0 ? fmi2OK : report(c, fmi2Error, "the model has no String variables");
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    instance *m = c;
    for (size_t i = 0; i < nvr; i++) { /* check the whole call before storing anything */
        if (vr[i] >= N_REAL)
            return report(m, fmi2Error, "no Real variable has value reference %u", vr[i]);
        if (check_settable(m, REAL_KIND[vr[i]], REAL_NAME[vr[i]]) != fmi2OK)
            return fmi2Error;
        if (!isfinite(value[i]))
            return report(m, fmi2Error, "%s = %g is not a finite number (value not applied)", REAL_NAME[vr[i]],
                          value[i]);
    }
    for (size_t i = 0; i < nvr; i++)
        *real_at(m, vr[i]) = value[i];
    if (nvr > 0)
        m->s.outputs_valid = 0;
    return fmi2OK;
}

static fmi2Status set_int(instance *m, const fmi2ValueReference vr[], size_t nvr, const int value[], int boolean)
{
    var_kind kind;
    const char *name;
    for (size_t i = 0; i < nvr; i++) {
        if (int_ref(m, vr[i], boolean, &kind, &name) == NULL)
            return report(m, fmi2Error, "no %s variable has value reference %u", boolean ? "Boolean" : "Integer",
                          vr[i]);
        if (check_settable(m, kind, name) != fmi2OK)
            return fmi2Error;
    }
    for (size_t i = 0; i < nvr; i++)
        *int_ref(m, vr[i], boolean, &kind, &name) = value[i];
    if (nvr > 0)
        m->s.outputs_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    return set_int(c, vr, nvr, value, 0);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    return set_int(c, vr, nvr, value, 1);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    (void)vr;
    (void)value;
    return nvr == 0 ? fmi2OK : report(c, fmi2Error, "the model has no String variables");
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    instance *m = c;
    if (*state == NULL)
        *state = malloc(sizeof(snapshot));
    if (*state == NULL)
        return report(m, fmi2Error, "out of memory");
    memcpy(*state, &m->s, sizeof(snapshot));
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state)
{
    instance *m = c;
    if (state == NULL)
        return report(m, fmi2Error, "fmi2SetFMUstate: no state given");
    memcpy(&m->s, state, sizeof(snapshot));
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state)
{
    (void)c;
    free(*state);
    *state = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size)
{
    (void)c;
    (void)state;
    *size = sizeof SNAPSHOT_MAGIC + sizeof(snapshot);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte bytes[], size_t size)
{
    instance *m = c;
    if (size < sizeof SNAPSHOT_MAGIC + sizeof(snapshot))
        return report(m, fmi2Error, "serialisation buffer too small");
    memcpy(bytes, SNAPSHOT_MAGIC, sizeof SNAPSHOT_MAGIC);
    memcpy(bytes + sizeof SNAPSHOT_MAGIC, state, sizeof(snapshot));
    return fmi2OK;
}

/* Serialised states come from files: check them like any other outside input. */
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *state)
{
    instance *m = c;
    snapshot s;
    if (size != sizeof SNAPSHOT_MAGIC + sizeof s || memcmp(bytes, SNAPSHOT_MAGIC, sizeof SNAPSHOT_MAGIC))
        return report(m, fmi2Error, "not a serialised state of this model (size %zu)", size);
    memcpy(&s, bytes + sizeof SNAPSHOT_MAGIC, sizeof s);
    int ok = s.mode >= MODE_INSTANTIATED && s.mode <= MODE_TERMINATED && isfinite(s.time);
    for (int i = 0; ok && i < QR_NSTATE; i++)
        ok = isfinite(s.st.y[i]);
    if (ok && s.mode == MODE_STEP)
        ok = qr_check_params(&s.par) == NULL;
    if (!ok)
        return report(m, fmi2Error, "serialised state is corrupt");
    s.outputs_valid = 0;
    if (*state == NULL)
        *state = malloc(sizeof s);
    if (*state == NULL)
        return report(m, fmi2Error, "out of memory");
    memcpy(*state, &s, sizeof s);
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[])
{
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return report(c, fmi2Error, "directional derivatives are not provided");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return report(c, fmi2Error, "input derivatives are not supported");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    return report(c, fmi2Error, "output derivatives are not supported");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    instance *m = c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (m->s.mode != MODE_STEP)
        return report(m, fmi2Error, "fmi2DoStep is not allowed in %s mode", MODE_NAMES[m->s.mode]);
    if (!(communicationStepSize > 0) || !isfinite(communicationStepSize))
        return report(m, fmi2Error, "communication step %g must be positive and finite", communicationStepSize);
    if (!(fabs(currentCommunicationPoint - m->s.time) <= 1e-6))
        return report(m, fmi2Error, "communication point %.9g is not the instance's time %.9g",
                      currentCommunicationPoint, m->s.time);
    if (qr_advance(&m->s.par, &m->s.in, &m->s.st, communicationStepSize) != 0)
        return report(m, fmi2Error, "the step from t = %.9g gave a non-finite state (state kept)", m->s.time);
    m->s.time = currentCommunicationPoint + communicationStepSize;
    m->s.outputs_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { return report(c, fmi2Error, "steps are synchronous; nothing to cancel"); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s;
    (void)value;
    return report(c, fmi2Discard, "fmi2GetStatus: steps are synchronous");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    instance *m = c;
    if (s != fmi2LastSuccessfulTime)
        return report(m, fmi2Discard, "status kind not provided");
    *value = m->s.time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)s;
    (void)value;
    return report(c, fmi2Discard, "status kind not provided");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    (void)s;
    (void)value;
    return report(c, fmi2Discard, "status kind not provided");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)s;
    (void)value;
    return report(c, fmi2Discard, "status kind not provided");
}
