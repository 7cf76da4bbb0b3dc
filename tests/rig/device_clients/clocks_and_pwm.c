/* A C DUT for `rig exec`: every libc clock and wait the shim virtualises, and sysfs PWM through stdio.
   Prints one "name value" line per measurement (nanoseconds of monotonic time unless said). */
#define _GNU_SOURCE
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/epoll.h>
#include <sys/select.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

static long long mono(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1000000000LL + ts.tv_nsec;
}

static int put(const char *path, const char *value)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    int ok = fputs(value, f) >= 0;
    return (fclose(f) == 0 && ok) ? 0 : -1;
}

int main(void)
{
    long long t = mono(), u;
    struct timespec req = { 0, 100000000 }, abs_ts;
    nanosleep(&req, NULL);
    u = mono();
    printf("nanosleep %lld\n", u - t);
    t = u;
    usleep(50000);
    u = mono();
    printf("usleep %lld\n", u - t);
    t = u;
    sleep(1);
    u = mono();
    printf("sleep %lld\n", u - t);
    t = u;
    clock_gettime(CLOCK_MONOTONIC, &abs_ts);
    abs_ts.tv_sec += 2;
    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &abs_ts, NULL);
    u = mono();
    printf("clock_nanosleep_abs %lld\n", u - t);
    t = u;
    req.tv_nsec = 20000000;
    clock_nanosleep(CLOCK_REALTIME, 0, &req, NULL);
    u = mono();
    printf("clock_nanosleep_rel %lld\n", u - t);
    t = u;
    struct timeval tv = { 0, 250000 };
    int r = select(0, NULL, NULL, NULL, &tv);
    u = mono();
    printf("select %lld %d\n", u - t, r);
    t = u;
    r = poll(NULL, 0, 300);
    u = mono();
    printf("poll %lld %d\n", u - t, r);
    t = u;
    int ep = epoll_create1(0);
    struct epoll_event ev;
    r = epoll_wait(ep, &ev, 1, 150);
    u = mono();
    printf("epoll_wait %lld %d\n", u - t, r);
    t = u;
    struct timespec rt, boot;
    struct timeval now;
    clock_gettime(CLOCK_REALTIME, &rt);
    gettimeofday(&now, NULL);
    clock_gettime(CLOCK_BOOTTIME, &boot);
    printf("realtime_s %lld\n", (long long)rt.tv_sec);
    printf("gettimeofday_minus_realtime_us %lld\n",
           (now.tv_sec - rt.tv_sec) * 1000000LL + now.tv_usec - rt.tv_nsec / 1000);
    printf("time_s %lld\n", (long long)time(NULL));
    printf("boottime_minus_monotonic %lld\n", boot.tv_sec * 1000000000LL + boot.tv_nsec - mono());

    const char *chip = "/sys/class/pwm/pwmchip0";
    char path[128];
    printf("pwm1_before_export %d\n", put("/sys/class/pwm/pwmchip0/pwm1/period", "20000000"));
    for (int ch = 0; ch < 4; ch++) {
        char value[32];
        snprintf(value, sizeof value, "%d", ch);
        snprintf(path, sizeof path, "%s/export", chip);
        if (put(path, value)) {
            perror("export");
            return 1;
        }
        snprintf(path, sizeof path, "%s/pwm%d/period", chip, ch);
        if (put(path, "2500000")) {
            perror("period");
            return 1;
        }
        snprintf(path, sizeof path, "%s/pwm%d/duty_cycle", chip, ch);
        snprintf(value, sizeof value, "%d", 1100000 + 100000 * ch);
        if (put(path, value)) {
            perror("duty_cycle");
            return 1;
        }
        snprintf(path, sizeof path, "%s/pwm%d/enable", chip, ch);
        if (put(path, "1")) {
            perror("enable");
            return 1;
        }
    }
    FILE *f = fopen("/sys/class/pwm/pwmchip0/pwm2/duty_cycle", "r");
    long long duty = -1;
    if (!f || fscanf(f, "%lld", &duty) != 1) {
        perror("read duty_cycle");
        return 1;
    }
    fclose(f);
    printf("pwm2_duty_read %lld\n", duty);
    sleep(1); /* the rotors settle (motor time constant 20 ms) */
    return 0;
}
