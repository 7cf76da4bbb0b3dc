/* Several fixed steps of an FMI 2.0 co-simulation FMU in one call, for the world's plant (rig/world.py).
 *
 * Why: between two requests of a DUT the world steps the plant several times with its inputs
 * unchanged (four 1 ms steps per 250 Hz cycle of the reference FC). From Python each step is three
 * ctypes calls (fmi2SetReal, fmi2DoStep, fmi2GetReal) and a numpy row copy into the output history,
 * which cost about four times the physics. Here the same calls are made through the FMU's own FMI
 * function pointers, in the same order and with the same arithmetic, so a flight is bit-identical to
 * the one stepped from Python; only the crossings into C are fewer.
 */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))

typedef int (*set_real_fn)(void *c, const unsigned int vr[], size_t nvr, const double value[]);
typedef int (*do_step_fn)(void *c, double t, double h, int no_set_state_prior);
typedef int (*get_real_fn)(void *c, const unsigned int vr[], size_t nvr, double value[]);

/* Filled once by Python (plant/fmu.py, _Steps mirrors this layout); the pointers stay valid for the
 * life of the plant instance. */
struct rig_plant_steps {
    set_real_fn set_real;
    do_step_fn do_step;
    get_real_fn get_real;
    void *component;
    const unsigned int *u_vr;
    const double *u;
    size_t n_u;
    const unsigned int *y_vr;
    double *y;
    size_t n_y;
    double *t;    /* the plant's time (s): the communication point of the next step */
    double *ring; /* a history of output rows (n_y doubles each), or NULL */
    int64_t ring_rows;
    int32_t failed_call;   /* after a failure: 1 fmi2SetReal, 2 fmi2DoStep, 3 fmi2GetReal */
    int32_t failed_status; /* ... and the status it returned */
};

/* Steps ``n`` times by ``h`` seconds: the inputs written once before the first step, the outputs read
 * after each into ``y`` and, when there is a ring, copied into row (first_row + i) % ring_rows for
 * step i. Returns the steps completed; fewer than ``n`` when a call returned Discard or worse (the
 * call and its status are left in the struct). Warnings (status 1) pass, as fmu.py lets them. */
EXPORT int32_t rig_plant_steps(struct rig_plant_steps *s, int32_t n, double h, int32_t write_inputs, int64_t first_row)
{
    s->failed_call = s->failed_status = 0;
    if (write_inputs && n > 0) {
        int st = s->set_real(s->component, s->u_vr, s->n_u, s->u);
        if (st > 1) {
            s->failed_call = 1, s->failed_status = st;
            return 0;
        }
    }
    for (int32_t i = 0; i < n; i++) {
        int st = s->do_step(s->component, *s->t, h, 1);
        if (st > 1) {
            s->failed_call = 2, s->failed_status = st;
            return i;
        }
        st = s->get_real(s->component, s->y_vr, s->n_y, s->y);
        if (st > 1) {
            s->failed_call = 3, s->failed_status = st;
            return i;
        }
        *s->t += h;
        if (s->ring && s->ring_rows > 0) {
            int64_t row = (first_row + i) % s->ring_rows;
            memcpy(s->ring + (size_t)row * s->n_y, s->y, s->n_y * sizeof(double));
        }
    }
    return n;
}
