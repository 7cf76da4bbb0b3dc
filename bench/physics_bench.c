/* Steps per second of the C physics alone: one 1 ms advance plus the outputs, as one doStep and one
 * getReal of the FMU do, without FMI or Python. Prints "physics_steps_per_s <rate>". */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "quadrotor_physics.h"

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 1000000;
    qr_params par = { 0 };
    qr_inputs in = { 0 };
#define PARAM_INPUT(m, f) m.f
#define X(vr, field, KIND, start, nm) X_##KIND(field, start)
#define X_PARAM(field, start) par.field = start;
#define X_INPUT(field, start) in.field = start;
#define X_OUTPUT(field, start)
    QR_REAL_VARIABLES(X)
    QR_INTEGER_VARIABLES(X)
#undef X
    par.pd0 = -100.0;
    for (int i = 0; i < 4; i++)
        in.pwm_us[i] = 1511.0 + (i == 1 ? 3.0 : 0.0);
    qr_state s;
    qr_outputs out;
    qr_init_state(&par, &in, &s);
    double t0 = now();
    for (long k = 0; k < n; k++) {
        qr_advance(&par, &in, &s, 1e-3);
        qr_outputs_from(&par, &in, &s, &out);
    }
    double dt = now() - t0;
    printf("physics_steps_per_s %.0f\n", (double)n / dt);
    fprintf(stderr, "(final roll %.3f rad after %ld steps)\n", out.roll, n);
    return 0;
}
