/* A multi-threaded C DUT with the shape of ArduPilot's Linux HAL, for `rig exec --topology direct`:
 *   main-loop  400 Hz on absolute clock_nanosleep deadlines: the latest IMU sample under the bus mutex,
 *              four motors through dprintf on sysfs PWM, a semaphore posted every 40 cycles;
 *   timer      SCHED_FIFO (asked for), 1 kHz on relative clock_nanosleep, takes the bus mutex;
 *   i2c-bus    three timerfds in one epoll_wait(-1): the MPU-6050 at 1 kHz, the MS5611 at 100 Hz
 *              (each tick reads the last conversion and starts the next), the HMC5883L at 75 Hz;
 *              signals a condition variable after each barometer read;
 *   uart       poll(-1) on /dev/ttyRC0 and a 50 Hz timerfd together;
 *   ekf        pthread_cond_timedwait (CLOCK_MONOTONIC, 50 ms) on the barometer's condition;
 *   logger     sem_timedwait (1 s) on the main loop's semaphore;
 *   watchdog   epoll_pwait with a 100 ms timeout on an epoll with nothing in it;
 *   telemetry  select (1 s timeout) on a pipe the main loop writes a byte to every 100 cycles;
 * and SIGALRM from setitimer at 20 Hz. All eight meet at a barrier before their loops. After SECONDS of virtual time the main loop prints one
 * "name count first_ns last_ns" line per activity (monotonic times of its first and last event) and
 * exits. `threaded_fc spin` also starts a thread 'spinner' that reads the clock and never waits;
 * `threaded_fc spin-quiet` one that never reads it either. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <linux/i2c-dev.h>
#include <linux/i2c.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <semaphore.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/select.h>
#include <sys/time.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

#define SECONDS 2
#define NS 1000000000LL

struct tally {
    long n;
    long long first, last;
};

static long long mono(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * NS + ts.tv_nsec;
}

static void count(struct tally *t)
{
    long long now = mono();
    if (!t->n++)
        t->first = now;
    t->last = now;
}

static struct tally imu, baro, compass, loops, timer_ticks, uart_ticks, uart_reads, ekf_wakes, ekf_timeouts, logs,
    alarms, watchdog, telemetry;
static int telemetry_pipe[2];
static pthread_barrier_t all_started; /* as AP_HAL_Linux's Scheduler: every thread meets here first */
static volatile int serial_threads;

static void meet(void)
{
    if (pthread_barrier_wait(&all_started) == PTHREAD_BARRIER_SERIAL_THREAD)
        serial_threads++;
}
static volatile sig_atomic_t alarm_count;
static pthread_mutex_t bus_lock = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t baro_ready;
static pthread_mutex_t baro_lock = PTHREAD_MUTEX_INITIALIZER;
static long baro_seq;
static sem_t log_sem;
static int bus, duty[4];
static int16_t gyro_x;

static int xfer(int addr, const unsigned char *w, int nw, unsigned char *r, int nr)
{
    struct i2c_msg m[2] = { { (uint16_t)addr, 0, (uint16_t)nw, (unsigned char *)w },
                            { (uint16_t)addr, I2C_M_RD, (uint16_t)nr, r } };
    struct i2c_rdwr_ioctl_data d = { m, nr ? 2 : 1 };
    pthread_mutex_lock(&bus_lock);
    int ok = ioctl(bus, I2C_RDWR, &d) >= 0;
    pthread_mutex_unlock(&bus_lock);
    return ok;
}

static int periodic_timer(long long period_ns)
{
    int fd = timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC);
    struct itimerspec its = { { 0, period_ns }, { 0, period_ns } };
    timerfd_settime(fd, 0, &its, NULL);
    return fd;
}

static void *bus_thread(void *arg)
{
    (void)arg;
    pthread_setname_np(pthread_self(), "i2c-bus");
    meet();
    int timers[3] = { periodic_timer(1000000), periodic_timer(10000000), periodic_timer(13333333) };
    int ep = epoll_create1(EPOLL_CLOEXEC);
    for (int i = 0; i < 3; i++) {
        struct epoll_event ev = { .events = EPOLLIN, .data.u32 = (uint32_t)i };
        epoll_ctl(ep, EPOLL_CTL_ADD, timers[i], &ev);
    }
    xfer(0x77, (const unsigned char *)"\x48", 1, NULL, 0); /* the first conversion (D1, OSR 4096) */
    for (;;) {
        struct epoll_event ev[3];
        int n = epoll_wait(ep, ev, 3, -1);
        for (int i = 0; i < n; i++) {
            uint64_t ticks;
            read(timers[ev[i].data.u32], &ticks, sizeof ticks);
            unsigned char r[14];
            if (ev[i].data.u32 == 0 && xfer(0x68, (const unsigned char *)"\x43", 1, r, 2)) {
                count(&imu);
                gyro_x = (int16_t)(r[0] << 8 | r[1]);
            } else if (ev[i].data.u32 == 1 && xfer(0x77, (const unsigned char *)"\x00", 1, r, 3) &&
                       xfer(0x77, (const unsigned char *)"\x48", 1, NULL, 0)) {
                count(&baro);
                pthread_mutex_lock(&baro_lock);
                baro_seq++;
                pthread_cond_signal(&baro_ready);
                pthread_mutex_unlock(&baro_lock);
            } else if (ev[i].data.u32 == 2 && xfer(0x1E, (const unsigned char *)"\x03", 1, r, 6)) {
                count(&compass);
            }
        }
    }
    return NULL;
}

static void *timer_thread(void *arg)
{
    (void)arg;
    pthread_setname_np(pthread_self(), "timer");
    meet();
    struct timespec ms = { 0, 1000000 };
    for (;;) {
        clock_nanosleep(CLOCK_MONOTONIC, 0, &ms, NULL);
        pthread_mutex_lock(&bus_lock);
        count(&timer_ticks);
        pthread_mutex_unlock(&bus_lock);
    }
    return NULL;
}

static void *uart_thread(void *arg)
{
    (void)arg;
    pthread_setname_np(pthread_self(), "uart");
    meet();
    struct pollfd fds[2] = { { open("/dev/ttyRC0", O_RDWR | O_NOCTTY | O_NONBLOCK), POLLIN, 0 },
                             { periodic_timer(20000000), POLLIN, 0 } };
    for (;;) {
        if (poll(fds, 2, -1) <= 0)
            continue;
        char buf[64];
        if ((fds[0].revents & POLLIN) && read(fds[0].fd, buf, sizeof buf) > 0)
            count(&uart_reads);
        if (fds[1].revents & POLLIN) {
            uint64_t ticks;
            read(fds[1].fd, &ticks, sizeof ticks);
            count(&uart_ticks);
        }
    }
    return NULL;
}

static void *ekf_thread(void *arg)
{
    (void)arg;
    pthread_setname_np(pthread_self(), "ekf");
    meet();
    long seen = 0;
    pthread_mutex_lock(&baro_lock);
    for (;;) {
        struct timespec until;
        clock_gettime(CLOCK_MONOTONIC, &until);
        until.tv_nsec += 50000000;
        if (until.tv_nsec >= NS)
            until.tv_sec++, until.tv_nsec -= NS;
        int err = 0;
        while (baro_seq == seen && err == 0)
            err = pthread_cond_timedwait(&baro_ready, &baro_lock, &until);
        if (baro_seq != seen) {
            seen = baro_seq;
            count(&ekf_wakes);
        } else {
            count(&ekf_timeouts);
        }
    }
    return NULL;
}

static void *logger_thread(void *arg)
{
    (void)arg;
    pthread_setname_np(pthread_self(), "logger");
    meet();
    for (;;) {
        struct timespec until;
        clock_gettime(CLOCK_REALTIME, &until);
        until.tv_sec += 1;
        if (sem_timedwait(&log_sem, &until) == 0)
            count(&logs);
    }
    return NULL;
}

static void *watchdog_thread(void *arg)
{
    (void)arg;
    pthread_setname_np(pthread_self(), "watchdog");
    meet();
    int ep = epoll_create1(EPOLL_CLOEXEC);
    sigset_t none;
    sigemptyset(&none);
    for (;;) {
        struct epoll_event ev;
        if (epoll_pwait(ep, &ev, 1, 100, &none) == 0)
            count(&watchdog);
    }
    return NULL;
}

static void *telemetry_thread(void *arg)
{
    (void)arg;
    pthread_setname_np(pthread_self(), "telemetry");
    meet();
    for (;;) {
        fd_set r;
        FD_ZERO(&r);
        FD_SET(telemetry_pipe[0], &r);
        struct timeval second = { 1, 0 };
        char c;
        if (select(telemetry_pipe[0] + 1, &r, NULL, NULL, &second) == 1 && read(telemetry_pipe[0], &c, 1) == 1)
            count(&telemetry);
    }
    return NULL;
}

static void *spinner(void *arg)
{
    pthread_setname_np(pthread_self(), "spinner");
    volatile long spins = 0;
    for (;;) {
        if (arg)
            mono(); /* reads the clock, never waits */
        spins++;
    }
    return NULL;
}

static void on_alarm(int sig)
{
    (void)sig;
    alarm_count++;
}

static pthread_t start(const char *why, void *(*fn)(void *), int fifo, void *arg)
{
    pthread_attr_t attr;
    pthread_attr_init(&attr);
    if (fifo) { /* as AP_HAL_Linux's Thread::start: an explicit real-time policy */
        struct sched_param param = { .sched_priority = 15 };
        pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
        pthread_attr_setschedpolicy(&attr, SCHED_FIFO);
        pthread_attr_setschedparam(&attr, &param);
    }
    pthread_t t;
    int err = pthread_create(&t, &attr, fn, arg);
    if (err) {
        fprintf(stderr, "%s: %s\n", why, strerror(err));
        exit(1);
    }
    return t;
}

static void report(const char *name, const struct tally *t)
{
    printf("%s %ld %lld %lld\n", name, t->n, t->first, t->last);
}

int main(int argc, char **argv)
{
    pthread_setname_np(pthread_self(), "main-loop");
    mlockall(MCL_CURRENT | MCL_FUTURE);
    bus = open("/dev/i2c-1", O_RDWR);
    xfer(0x68, (const unsigned char *)"\x6b\x00", 2, NULL, 0); /* MPU-6050 out of sleep */
    xfer(0x77, (const unsigned char *)"\x1e", 1, NULL, 0);     /* MS5611 reset */
    xfer(0x1E, (const unsigned char *)"\x02\x00", 2, NULL, 0); /* HMC5883L continuous mode */
    int exp = open("/sys/class/pwm/pwmchip0/export", O_WRONLY);
    for (int m = 0; m < 4; m++) {
        char path[64];
        dprintf(exp, "%d", m);
        snprintf(path, sizeof path, "/sys/class/pwm/pwmchip0/pwm%d/period", m);
        int p = open(path, O_WRONLY);
        dprintf(p, "%d", 2500000);
        close(p);
        snprintf(path, sizeof path, "/sys/class/pwm/pwmchip0/pwm%d/duty_cycle", m);
        duty[m] = open(path, O_WRONLY);
        snprintf(path, sizeof path, "/sys/class/pwm/pwmchip0/pwm%d/enable", m);
        p = open(path, O_WRONLY);
        dprintf(p, "1");
        close(p);
    }
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_cond_init(&baro_ready, &ca);
    sem_init(&log_sem, 0, 0);
    pthread_barrier_init(&all_started, NULL, 8); /* the main loop and its seven threads */
    signal(SIGALRM, on_alarm);
    struct itimerval it = { { 0, 50000 }, { 0, 50000 } };
    setitimer(ITIMER_REAL, &it, NULL);

    start("timer", timer_thread, 1, NULL);
    start("i2c-bus", bus_thread, 0, NULL);
    start("uart", uart_thread, 0, NULL);
    start("ekf", ekf_thread, 0, NULL);
    start("logger", logger_thread, 0, NULL);
    pipe(telemetry_pipe);
    start("watchdog", watchdog_thread, 0, NULL);
    start("telemetry", telemetry_thread, 0, NULL);
    if (argc > 1 && strncmp(argv[1], "spin", 4) == 0)
        start("spinner", spinner, 0, strcmp(argv[1], "spin") == 0 ? (void *)1 : NULL);

    meet();
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    long alarms_seen = 0;
    for (int cycle = 1; cycle <= SECONDS * 400; cycle++) {
        next.tv_nsec += 2500000;
        if (next.tv_nsec >= NS)
            next.tv_sec++, next.tv_nsec -= NS;
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL) == EINTR)
            ;
        while (alarms_seen < alarm_count) {
            alarms_seen++;
            count(&alarms);
        }
        pthread_mutex_lock(&bus_lock);
        int g = gyro_x;
        pthread_mutex_unlock(&bus_lock);
        for (int m = 0; m < 4; m++)
            dprintf(duty[m], "%d", 1100000 + 1000 * (g & 1) + 100000 * m);
        count(&loops);
        if (cycle % 40 == 0)
            sem_post(&log_sem);
        if (cycle % 100 == 0)
            write(telemetry_pipe[1], "t", 1);
    }
    report("main_loop", &loops);
    report("timer", &timer_ticks);
    report("imu", &imu);
    report("baro", &baro);
    report("compass", &compass);
    report("uart_timer", &uart_ticks);
    report("uart_reads", &uart_reads);
    report("ekf_wakes", &ekf_wakes);
    report("ekf_timeouts", &ekf_timeouts);
    report("logger", &logs);
    report("alarm", &alarms);
    report("watchdog", &watchdog);
    report("telemetry", &telemetry);
    printf("barrier_serial %d 0 0\n", serial_threads);
    fflush(stdout);
    exit(0);
}
