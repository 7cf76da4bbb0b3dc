/* A C DUT that asks for real-time scheduling as ArduPilot's Linux HAL does: mlockall, SCHED_FIFO for
   the process, a SCHED_FIFO timer thread created with explicit attributes, pthread_setschedparam, and
   one request the kernel refuses whatever the privileges (priority 100). Prints "name value" lines:
   each call's result (0, or the errno's name) and the policy the thread really runs with. */
#define _GNU_SOURCE
#include <errno.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>

static void report(const char *name, int err) { printf("%s %s\n", name, err ? strerrorname_np(err) : "0"); }

static const char *policy(int p) { return p == SCHED_FIFO ? "SCHED_FIFO" : p == SCHED_RR ? "SCHED_RR" : "SCHED_OTHER"; }

static void *timer_thread(void *arg)
{
    (void)arg;
    struct sched_param param;
    int p;
    pthread_getschedparam(pthread_self(), &p, &param);
    printf("timer_thread_policy %s\n", policy(p));
    return NULL;
}

int main(void)
{
    pthread_setname_np(pthread_self(), "main-loop");
    report("mlockall", mlockall(MCL_CURRENT | MCL_FUTURE) ? errno : 0);
    struct sched_param param = { .sched_priority = 12 };
    report("sched_setscheduler", sched_setscheduler(0, SCHED_FIFO, &param) ? errno : 0);
    printf("main_policy %s\n", policy(sched_getscheduler(0)));
    param.sched_priority = 100;
    report("sched_setscheduler_out_of_range", sched_setscheduler(0, SCHED_FIFO, &param) ? errno : 0);

    pthread_attr_t attr;
    pthread_attr_init(&attr);
    pthread_attr_setinheritsched(&attr, PTHREAD_EXPLICIT_SCHED);
    pthread_attr_setschedpolicy(&attr, SCHED_FIFO);
    param.sched_priority = 15;
    pthread_attr_setschedparam(&attr, &param);
    pthread_t timer;
    int err = pthread_create(&timer, &attr, timer_thread, NULL);
    report("pthread_create_fifo", err);
    if (!err)
        pthread_join(timer, NULL);
    param.sched_priority = 10;
    report("pthread_setschedparam_rr", pthread_setschedparam(pthread_self(), SCHED_RR, &param));
    /* back to the ordinary policy, so a real-time run leaves nothing behind */
    param.sched_priority = 0;
    sched_setscheduler(0, SCHED_OTHER, &param);
    munlockall();
    return 0;
}
