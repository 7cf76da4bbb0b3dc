/*
 * The pthread objects threads meet at, under the rule (threads.c) in lockstep: mutexes and read-write
 * locks another thread holds, condition variables, semaphores and barriers. A thread blocked in glibc's
 * would hold the turn while the thread it waits for cannot run; here it waits under the rule until a
 * look that consumes nothing says it can go on. Part of rigshim.c (one translation unit): see its top
 * comment.
 */

/* A mutex another thread holds: wait (the holder runs until it waits or unlocks) until it looks free,
   then take it. glibc's lock word is 0 when nobody holds it. */
static int mutex_free(void *m) { return ((pthread_mutex_t *)m)->__data.__lock == 0; }

static int mutex_wait(pthread_mutex_t *m, uint64_t deadline)
{
    for (;;) {
        int err = LOAD(pthread_mutex_trylock)(m);
        if (err != EBUSY)
            return err;
        if (m->__data.__owner == gettid())
            return EDEADLK; /* (an error-checking mutex this thread holds) */
        if (now_peek() >= deadline)
            return ETIMEDOUT;
        rule_wait(deadline, mutex_free, m, 0);
    }
}

EXPORT int pthread_mutex_lock(pthread_mutex_t *m)
{
    if (!threaded || my_slot <= 0 || !lockstep)
        return LOAD(pthread_mutex_lock)(m);
    int err = mutex_wait(m, RIG_WAIT_FOREVER);
    if (err == EDEADLK && (m->__data.__kind & 3) != PTHREAD_MUTEX_ERRORCHECK)
        return LOAD(pthread_mutex_lock)(m); /* (a normal mutex locked twice deadlocks, as without the rig) */
    return err;
}

/* A deadline on a clock, as a sim time (0 for one already past). */
static uint64_t sim_deadline(clockid_t clock, const struct timespec *abs) { return sim_time_on(clock, ts_ns(abs)); }

EXPORT int pthread_mutex_timedlock(pthread_mutex_t *m, const struct timespec *abs)
{
    if (!threaded || my_slot <= 0 || !lockstep)
        return LOAD(pthread_mutex_timedlock)(m, abs);
    if (!valid_ts(abs))
        return EINVAL;
    return mutex_wait(m, sim_deadline(CLOCK_REALTIME, abs));
}

/* A read-write lock another thread holds: wait until a try would take it (the rule's look takes it and
   gives it back at once, so the lock's owner is always the thread that holds it), then take it. */
struct rwlock_look {
    pthread_rwlock_t *l;
    int write;
};

static int rwlock_try(pthread_rwlock_t *l, int write)
{
    return write ? LOAD(pthread_rwlock_trywrlock)(l) : LOAD(pthread_rwlock_tryrdlock)(l);
}

static int rwlock_free(void *p)
{
    struct rwlock_look *look = p;
    if (rwlock_try(look->l, look->write))
        return 0;
    LOAD(pthread_rwlock_unlock)(look->l);
    return 1;
}

static int rwlock_wait(pthread_rwlock_t *l, int write, uint64_t deadline)
{
    struct rwlock_look look = { l, write };
    for (;;) {
        int err = rwlock_try(l, write);
        if (err != EBUSY)
            return err;
        if (now_peek() >= deadline)
            return ETIMEDOUT;
        rule_wait(deadline, rwlock_free, &look, 0);
    }
}

/* The read-write locks are the rule's once several threads run (else glibc's). */
#define RWLOCK_CALLS(name, write)                                                                                 \
    EXPORT int pthread_rwlock_##name##lock(pthread_rwlock_t *l)                                                   \
    {                                                                                                             \
        if (!threaded || my_slot <= 0 || !lockstep)                                                               \
            return LOAD(pthread_rwlock_##name##lock)(l);                                                          \
        return rwlock_wait(l, write, RIG_WAIT_FOREVER);                                                           \
    }                                                                                                             \
    EXPORT int pthread_rwlock_timed##name##lock(pthread_rwlock_t *l, const struct timespec *abs)                  \
    {                                                                                                             \
        if (!threaded || my_slot <= 0 || !lockstep)                                                               \
            return LOAD(pthread_rwlock_timed##name##lock)(l, abs);                                                \
        return valid_ts(abs) ? rwlock_wait(l, write, sim_deadline(CLOCK_REALTIME, abs)) : EINVAL;                 \
    }                                                                                                             \
    EXPORT int pthread_rwlock_clock##name##lock(pthread_rwlock_t *l, clockid_t clock, const struct timespec *abs) \
    {                                                                                                             \
        if (!threaded || my_slot <= 0 || !lockstep)                                                               \
            return LOAD(pthread_rwlock_clock##name##lock)(l, clock, abs);                                         \
        if (!valid_ts(abs) || (clock != CLOCK_REALTIME && clock != CLOCK_MONOTONIC))                              \
            return EINVAL;                                                                                        \
        return rwlock_wait(l, write, sim_deadline(clock, abs));                                                   \
    }
RWLOCK_CALLS(rd, 0)
RWLOCK_CALLS(wr, 1)

/* A condition variable: the waiters the rule knows, in the order they began to wait; a signal makes
   the first signalled (it goes on when the rule picks it), a broadcast all. */
struct cond_wait {
    pthread_cond_t *cond;
    uint64_t seq;
    int signalled;
};
static struct cond_wait *cond_waits[MAX_THREADS];
static uint64_t cond_seq;

static int signalled(void *w) { return ((struct cond_wait *)w)->signalled; }

static int cond_wait_virtual(pthread_cond_t *c, pthread_mutex_t *m, uint64_t deadline)
{
    struct cond_wait w = { c, cond_seq++, 0 };
    cond_waits[me()] = &w;
    LOAD(pthread_mutex_unlock)(m);
    rule_wait(deadline, signalled, &w, 0);
    cond_waits[me()] = NULL;
    int err = threaded ? mutex_wait(m, RIG_WAIT_FOREVER) : LOAD(pthread_mutex_lock)(m);
    return err ? err : w.signalled ? 0 : ETIMEDOUT;
}

static void cond_wake(pthread_cond_t *c, int all)
{
    for (;;) {
        struct cond_wait *first = NULL;
        for (int i = 0; i < n_vthreads; i++) {
            struct cond_wait *w = cond_waits[i];
            if (w && w->cond == c && !w->signalled && (!first || w->seq < first->seq))
                first = w;
        }
        if (!first)
            return;
        first->signalled = 1;
        if (!all)
            return;
    }
}

/* glibc keeps the clock of a condition variable in __wrefs (bit 1: CLOCK_MONOTONIC). */
static clockid_t cond_clock(const pthread_cond_t *c)
{
    return (c->__data.__wrefs & 2) ? CLOCK_MONOTONIC : CLOCK_REALTIME;
}

static int cond_ruled(void) { return lockstep && active && my_slot > 0; }

EXPORT int pthread_cond_wait(pthread_cond_t *c, pthread_mutex_t *m)
{
    if (!cond_ruled())
        return LOAD(pthread_cond_wait)(c, m);
    return cond_wait_virtual(c, m, RIG_WAIT_FOREVER);
}

EXPORT int pthread_cond_timedwait(pthread_cond_t *c, pthread_mutex_t *m, const struct timespec *abs)
{
    if (!cond_ruled())
        return LOAD(pthread_cond_timedwait)(c, m, abs);
    if (!valid_ts(abs))
        return EINVAL;
    return cond_wait_virtual(c, m, sim_deadline(cond_clock(c), abs));
}

EXPORT int pthread_cond_clockwait(pthread_cond_t *c, pthread_mutex_t *m, clockid_t clock, const struct timespec *abs)
{
    if (!cond_ruled())
        return LOAD(pthread_cond_clockwait)(c, m, clock, abs);
    if (!valid_ts(abs) || (clock != CLOCK_REALTIME && clock != CLOCK_MONOTONIC))
        return EINVAL;
    return cond_wait_virtual(c, m, sim_deadline(clock, abs));
}

EXPORT int pthread_cond_signal(pthread_cond_t *c)
{
    if (cond_ruled())
        cond_wake(c, 0);
    return LOAD(pthread_cond_signal)(c);
}

EXPORT int pthread_cond_broadcast(pthread_cond_t *c)
{
    if (cond_ruled())
        cond_wake(c, 1);
    return LOAD(pthread_cond_broadcast)(c);
}

static int sem_positive(void *s)
{
    int v = 0;
    sem_getvalue((sem_t *)s, &v);
    return v > 0;
}

/* sem_wait and its deadlines: take it if it is up, else wait under the rule until it is (another
   thread's sem_post) or the deadline passes. */
static int sem_wait_virtual(sem_t *s, uint64_t deadline)
{
    for (;;) {
        if (LOAD(sem_trywait)(s) == 0)
            return 0;
        if (errno != EAGAIN)
            return -1;
        if (now_peek() >= deadline)
            return errno_ret(ETIMEDOUT);
        if (rule_wait(deadline, sem_positive, s, 0))
            return errno_ret(EINTR);
    }
}

EXPORT int sem_wait(sem_t *s) { return cond_ruled() ? sem_wait_virtual(s, RIG_WAIT_FOREVER) : LOAD(sem_wait)(s); }

EXPORT int sem_timedwait(sem_t *s, const struct timespec *abs)
{
    if (!cond_ruled())
        return LOAD(sem_timedwait)(s, abs);
    if (!valid_ts(abs))
        return errno_ret(EINVAL);
    return sem_wait_virtual(s, sim_deadline(CLOCK_REALTIME, abs));
}

EXPORT int sem_clockwait(sem_t *s, clockid_t clock, const struct timespec *abs)
{
    if (!cond_ruled())
        return LOAD(sem_clockwait)(s, clock, abs);
    if (!valid_ts(abs) || (clock != CLOCK_REALTIME && clock != CLOCK_MONOTONIC))
        return errno_ret(EINVAL);
    return sem_wait_virtual(s, sim_deadline(clock, abs));
}

/* Barriers (AP_HAL_Linux's threads meet at one before they start their loops): kept here in lockstep,
   since a thread blocked in glibc's would hold the turn. The last to arrive goes on with
   PTHREAD_BARRIER_SERIAL_THREAD, as in glibc; the others when the rule picks them. */
#define MAX_BARRIERS 16
static struct {
    pthread_barrier_t *b;
    unsigned count, arrived;
    uint64_t round;
} barriers[MAX_BARRIERS];

struct barrier_wait {
    int slot;
    uint64_t round;
};

static int barrier_passed(void *w)
{
    struct barrier_wait *bw = w;
    return barriers[bw->slot].round != bw->round;
}

static int barrier_slot(const pthread_barrier_t *b)
{
    for (int i = 0; i < MAX_BARRIERS; i++)
        if (barriers[i].b == b)
            return i;
    return -1;
}

EXPORT int pthread_barrier_init(pthread_barrier_t *b, const pthread_barrierattr_t *attr, unsigned count)
{
    int err = LOAD(pthread_barrier_init)(b, attr, count);
    if (err || !lockstep || !active)
        return err;
    int slot = barrier_slot(b);
    for (int i = 0; i < MAX_BARRIERS && slot < 0; i++)
        if (!barriers[i].b)
            slot = i;
    if (slot >= 0) { /* (more barriers than slots: the rest are glibc's) */
        barriers[slot].b = b;
        barriers[slot].count = count;
        barriers[slot].arrived = 0;
    }
    return 0;
}

EXPORT int pthread_barrier_destroy(pthread_barrier_t *b)
{
    int slot = barrier_slot(b);
    if (slot >= 0)
        barriers[slot].b = NULL;
    return LOAD(pthread_barrier_destroy)(b);
}

EXPORT int pthread_barrier_wait(pthread_barrier_t *b)
{
    int slot = cond_ruled() ? barrier_slot(b) : -1;
    if (slot < 0)
        return LOAD(pthread_barrier_wait)(b);
    if (++barriers[slot].arrived == barriers[slot].count) {
        barriers[slot].arrived = 0;
        barriers[slot].round++;
        return PTHREAD_BARRIER_SERIAL_THREAD;
    }
    struct barrier_wait w = { slot, barriers[slot].round };
    rule_wait(RIG_WAIT_FOREVER, barrier_passed, &w, 0);
    return 0;
}
