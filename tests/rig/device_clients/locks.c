/* A C DUT whose threads meet at locks another thread holds across a sleep: a mutex, a timed mutex lock
   that gives up, and a read-write lock. Prints "name result ns" (monotonic ns since the start when the
   lock was had, or given up). */
#define _GNU_SOURCE
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

static long long t0;
static pthread_mutex_t m = PTHREAD_MUTEX_INITIALIZER;
static pthread_rwlock_t rw = PTHREAD_RWLOCK_INITIALIZER;

static long long since(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1000000000LL + ts.tv_nsec - t0;
}

static void nap_ms(long ms)
{
    struct timespec d = { 0, ms * 1000000 };
    nanosleep(&d, NULL);
}

static void *hold_mutex(void *ms)
{
    pthread_mutex_lock(&m);
    nap_ms((long)ms);
    pthread_mutex_unlock(&m);
    return NULL;
}

static void *hold_write(void *ms)
{
    pthread_rwlock_wrlock(&rw);
    nap_ms((long)ms);
    pthread_rwlock_unlock(&rw);
    return NULL;
}

static void after(const char *name, void *(*holder)(void *), long ms, int (*take)(void))
{
    pthread_t t;
    long long start = since();
    pthread_create(&t, NULL, holder, (void *)ms);
    nap_ms(1); /* the holder takes the lock first */
    int err = take();
    printf("%s %s %lld\n", name, err ? strerrorname_np(err) : "0", since() - start);
    fflush(stdout);
    pthread_join(t, NULL);
}

static int take_mutex(void)
{
    int err = pthread_mutex_lock(&m);
    pthread_mutex_unlock(&m);
    return err;
}

static int give_up_at_5ms(void)
{
    struct timespec until;
    clock_gettime(CLOCK_REALTIME, &until);
    until.tv_nsec += 4000000; /* 4 ms from now, 5 ms from the start */
    if (until.tv_nsec >= 1000000000)
        until.tv_sec++, until.tv_nsec -= 1000000000;
    int err = pthread_mutex_timedlock(&m, &until);
    if (!err)
        pthread_mutex_unlock(&m);
    return err;
}

static int take_read(void)
{
    int err = pthread_rwlock_rdlock(&rw);
    pthread_rwlock_unlock(&rw);
    return err;
}

int main(void)
{
    t0 = since();
    after("mutex", hold_mutex, 10, take_mutex);
    after("mutex_timedlock", hold_mutex, 10, give_up_at_5ms);
    after("rwlock_read", hold_write, 20, take_read);
    return 0;
}
