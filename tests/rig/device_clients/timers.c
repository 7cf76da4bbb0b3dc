/* A single-threaded C DUT on virtual timers: a periodic timerfd read blocking and not, its gettime,
   expirations that pile up during a sleep, alarm ending a sleep early (EINTR), setitimer/getitimer.
   Prints one "name value..." line per measurement (times: ns of monotonic time since the start). */
#define _GNU_SOURCE
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/time.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

static long long t0;

static long long since(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1000000000LL + ts.tv_nsec - t0;
}

static void on_alarm(int sig) { (void)sig; }

int main(void)
{
    t0 = since();
    int fd = timerfd_create(CLOCK_MONOTONIC, 0);
    struct itimerspec every10ms = { { 0, 10000000 }, { 0, 10000000 } }, cur;
    timerfd_settime(fd, 0, &every10ms, NULL);
    for (int i = 0; i < 3; i++) {
        uint64_t n = 0;
        ssize_t k = read(fd, &n, sizeof n);
        printf("read%d %zd %llu %lld\n", i, k, (unsigned long long)n, since());
    }
    timerfd_gettime(fd, &cur);
    printf("gettime %ld %ld\n", cur.it_value.tv_nsec, cur.it_interval.tv_nsec);
    struct timespec nap = { 0, 35000000 };
    nanosleep(&nap, NULL); /* 3.5 periods: three expirations counted */
    uint64_t n = 0;
    read(fd, &n, sizeof n);
    printf("after_sleep %llu\n", (unsigned long long)n);
    char small[4];
    ssize_t k = read(fd, small, sizeof small);
    printf("short_read %zd %s\n", k, strerrorname_np(errno));
    struct itimerspec off = { 0 };
    timerfd_settime(fd, 0, &off, NULL);
    int nb = timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK);
    k = read(nb, &n, sizeof n);
    printf("nonblocking %zd %s\n", k, strerrorname_np(errno));
    struct itimerspec abs = { { 0, 0 }, { 0, 0 } };
    clock_gettime(CLOCK_MONOTONIC, &abs.it_value);
    abs.it_value.tv_sec += 1;
    timerfd_settime(nb, TFD_TIMER_ABSTIME, &abs, NULL);
    long long start = since();
    struct pollfd p = { nb, POLLIN, 0 };
    int ready = poll(&p, 1, -1); /* a timerfd in poll, no timeout: ready at its absolute time */
    printf("poll_abs %d %lld\n", ready, since() - start);
    signal(SIGALRM, on_alarm);
    start = since();
    alarm(1);
    unsigned left = sleep(5);
    printf("alarm_sleep %u %lld\n", left, since() - start);
    struct itimerval it = { { 0, 250000 }, { 0, 250000 } }, got; /* every 250 ms */
    setitimer(ITIMER_REAL, &it, NULL);
    getitimer(ITIMER_REAL, &got);
    printf("getitimer %ld %ld\n", (long)got.it_value.tv_sec, (long)got.it_value.tv_usec);
    start = since();
    struct timespec long_nap = { 2, 0 }, rem;
    int r = nanosleep(&long_nap, &rem);
    printf("nanosleep_interrupted %d %s %lld %ld\n", r, strerrorname_np(errno), since() - start, rem.tv_nsec);
    start = since();
    r = pause(); /* the next expiry of the 250 ms interval */
    printf("pause %d %s %lld\n", r, strerrorname_np(errno), since() - start);
    return 0;
}
