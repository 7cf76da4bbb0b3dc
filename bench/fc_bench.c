/* Time per update of each estimator of the reference FC and per control cycle (PIDs + mixer), on a
   recorded-style motion. Prints rates and the Mahony/EKF ratio (seed 002 Table 1: about one half). */
#include <math.h>
#include <stdio.h>
#include <time.h>

#include "canned_motion.h"
#include "fc.h"

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

int main(void)
{
    enum { N = 200000 };
    static vec3 gyro[N], acc[N], mag[N];
    for (int k = 0; k < N; k++)
        canned_motion(k, &gyro[k], &acc[k], &mag[k]);
    quat_cf cf;
    mahony_dcm mh;
    ekf7 kf;
    quat_cf_init(&cf, 0.3, 0.01);
    mahony_init(&mh, 0.3, 0.01);
    ekf_init(&kf);
    double t0 = now();
    for (int k = 0; k < N; k++)
        quat_cf_update(&cf, gyro[k], acc[k], mag[k], 0.004);
    double t_cf = (now() - t0) / N;
    t0 = now();
    for (int k = 0; k < N; k++)
        mahony_update(&mh, gyro[k], acc[k], mag[k], 0.004);
    double t_mh = (now() - t0) / N;
    t0 = now();
    for (int k = 0; k < N / 10; k++)
        ekf_update(&kf, gyro[k], acc[k], mag[k], 0.004);
    double t_kf = (now() - t0) / (N / 10);
    pid pids[5];
    for (int i = 0; i < 5; i++)
        pid_init(&pids[i], 1, 0.1, 0.01, 100, 50);
    double out[4], sink = 0;
    t0 = now();
    for (int k = 0; k < N; k++) {
        double r = pid_step(&pids[1], pid_step(&pids[0], 0.1 - acc[k].x * 0.01, 0.004) - gyro[k].x, 0.004);
        double p = pid_step(&pids[3], pid_step(&pids[2], -0.1 - acc[k].y * 0.01, 0.004) - gyro[k].y, 0.004);
        double y = pid_step(&pids[4], -gyro[k].z, 0.004);
        mix(MIXER_PLUS, 500, r, p, y, out);
        for (int i = 0; i < 4; i++)
            sink += throttle_compensate(out[i], 1.02, 3);
    }
    double t_ctl = (now() - t0) / N;
    printf("reference FC, per update (%d updates):\n", N);
    printf("  seed-000 quaternion filter %8.3f us  (%.0f k/s)\n", t_cf * 1e6, 1e-3 / t_cf);
    printf("  seed-002 Mahony DCM        %8.3f us  (%.0f k/s)\n", t_mh * 1e6, 1e-3 / t_mh);
    printf("  EKF (7 states)             %8.3f us  (%.0f k/s)\n", t_kf * 1e6, 1e-3 / t_kf);
    printf("  Mahony / EKF time ratio    %8.3f  (seed 002 Table 1: about 0.5)\n", t_mh / t_kf);
    printf("  control cycle (5 PIDs, mixer, eq. 16) %8.3f us  (checksum %.1f)\n", t_ctl * 1e6, sink);
    return 0;
}
